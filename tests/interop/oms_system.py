"""Builds and runs a co-simulation system in OMSimulator through its C API: `main(spec)`, run by
conftest's `oms_system` with OMSimulator's Python module on the path, in a process of its own
(the API keeps global state in its shared library), or from the command line with the spec as
its one argument (JSON). The spec:

- `instances`: [{"name", "fmu", "parameters": {variable: [kind, value]}}], kind one of Real,
  Integer, Boolean (the variable's type in the FMU's model description);
- `connections`: [["a.y", "b.u"], ...] as in our system TOMLs;
- `model_exchange`: the name of the instance to run through its Model Exchange interface, or
  null: that instance goes into a strongly coupled system `ode` of its own, integrated by
  CVode (`rtol`, maximum step `h_max`), whose connectors carry its connections;
- `step`, `stop`, `out` (result file), and `ssp`: when given, the model is also written there
  as an SSP file (`oms_export`) before it runs.

The root is a weakly coupled (co-simulation) system with the fixed step `step`. The ME
instance's connections go through connectors of the `ode` system (`ode.crane_x`), unless
`ports` is false: a connection from the root straight to `ode.crane.x` runs, but OMSimulator
exports it with a connector that no element of the root has (it reports
`[getBusConnector] "crane.x" is not a valid ident` while exporting and again while running the
SSP file). Through the connectors, OMSimulator (2.1) does not pass the ME instance's initial
outputs on during initialization: the CS FMUs' values at t = 0 see 0 there (from the first
step on they see the plant's values); straight connections pass them.
"""

import json
import sys
import tempfile

from OMSimulator import Capi

CAUSALITY_INPUT, CAUSALITY_OUTPUT, SIGNAL_REAL = 0, 1, 0


def ok(status, what):
    assert status.value == 0, f"{what}: {status}"


def main(spec):
    ok(Capi.setCommandLineOption("--suppressPath=true"), "options")
    ok(Capi.setTempDirectory(tempfile.mkdtemp()), "temp directory")
    ok(Capi.newModel("model"), "newModel")
    ok(Capi.addSystem("model.root", 1), "root (weakly coupled)")
    where = {}
    for instance in spec["instances"]:
        name = instance["name"]
        cref = f"model.root.{name}"
        if name == spec["model_exchange"]:
            ok(Capi.addSystem("model.root.ode", 2), "ode (strongly coupled)")
            ok(Capi.setSolver("model.root.ode", 3), "CVode")
            ok(Capi.setTolerance("model.root.ode", spec["rtol"]), "tolerance")
            ok(Capi.setVariableStepSize("model.root.ode", 1e-6, 1e-12, spec["h_max"]), "steps")
            cref = f"model.root.ode.{name}"
        ok(Capi.addSubModel(cref, instance["fmu"]), name)
        where[name] = cref

    ports = set()

    def end(reference, causality):
        name, variable = reference.split(".", 1)
        if not spec.get("ports", True) or not where[name].startswith("model.root.ode."):
            return f"{where[name]}.{variable}"
        port = f"model.root.ode.{name}_" + "".join(
            "_" if c in "[," else c for c in variable if c != "]"
        )
        if port not in ports:
            ports.add(port)
            ok(Capi.addConnector(port, causality, SIGNAL_REAL), port)
            inner = (f"{where[name]}.{variable}", port)
            ok(Capi.addConnection(*(inner if causality == CAUSALITY_OUTPUT else inner[::-1])), port)
        return port

    for a, b in spec["connections"]:
        ok(Capi.addConnection(end(a, CAUSALITY_OUTPUT), end(b, CAUSALITY_INPUT)), f"{a} -> {b}")
    ok(Capi.setFixedStepSize("model.root", spec["step"]), "step")
    ok(Capi.setResultFile("model", spec["out"]), "result file")
    ok(Capi.setStopTime("model", spec["stop"]), "stop time")
    for instance in spec["instances"]:
        for variable, (kind, value) in instance["parameters"].items():
            cref = f"{where[instance['name']]}.{variable}"
            ok(getattr(Capi, f"set{kind}")(cref, value), cref)
    if spec.get("ssp"):
        status = Capi.obj.oms_export(b"model", spec["ssp"].encode())
        assert status == 0, f"oms_export: status {status}"
    ok(Capi.instantiate("model"), "instantiate")
    ok(Capi.initialize("model"), "initialize")
    ok(Capi.simulate("model"), "simulate")
    ok(Capi.terminate("model"), "terminate")
    ok(Capi.delete("model"), "delete")


if __name__ == "__main__":
    main(json.loads(sys.argv[1]))
