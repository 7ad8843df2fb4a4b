"""The Model Exchange FMUs of the repository and their scenarios, for the tests that run them
(tests/fmpy/test_model_exchange.py, tests/interop/test_model_exchange_fmucheck.py).

- `stems(repo)`: the bundled variants whose committed FMI 2.0 description declares
  `<ModelExchange>`;
- `load(repo)`: every `fmus/<Id>/me_scenarios.py`'s SCENARIOS (fields: see
  tests/fmpy/test_model_exchange.py) and, by FMU, its optional `random_point`.
"""

import importlib.util


def stems(repo):
    return [
        p.stem
        for p in sorted((repo / "modelDescription").glob("*.xml"))
        if "<ModelExchange " in p.read_text()
    ]


def load(repo):
    scenarios, samplers = [], {}
    for path in sorted((repo / "fmus").glob("*/me_scenarios.py")):
        spec = importlib.util.spec_from_file_location(f"me_scenarios_{path.parent.name}", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        for s in module.SCENARIOS:
            scenarios.append(s)
            if hasattr(module, "random_point"):
                samplers[s["fmu"]] = module.random_point
    return scenarios, samplers
