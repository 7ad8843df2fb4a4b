"""OMSimulator's Model Exchange run of one FMU, timed in process, for scripts/bench-me: a
worker that reads one request a line (JSON) on stdin and answers one line on stdout,
`oms_me: ` and JSON (OMSimulator's log goes to /dev/null).

A request: {"fmu", "rtol", "stop", "step", "out", "outputs": [names], "parameters": {name:
value}} (Real start values). The FMU goes into a
strongly coupled system `ode` integrated by CVODE at relative tolerance `rtol` (initial step
1e-6, least 1e-12, largest `step`: with a larger one, its first step runs to the stop time and
every output point prints the end state), inside the root (weakly coupled) that steps every `step`
(OMSimulator's way to run an ME FMU, as tests/interop/oms_system.py does): its `outputs` are
logged at every such step into the CSV `out`. The answer: {"seconds": wall time of oms_simulate alone} (instantiation and
initialisation before it, not timed), or {"error": message}.

Run with OMSimulator's Python module on PYTHONPATH, in a process of its own (the API keeps
global state in its shared library); each request builds and deletes a model of its own.
"""

import json
import os
import re
import sys
import tempfile
import time

from OMSimulator import Capi

# What starts an answer's line (OMSimulator may print on stdout too).
ANSWER = "oms_me: "
SYSTEM_WC, SYSTEM_SC, SOLVER_CVODE = 1, 2, 3


def ok(status, what):
    if status.value != 0:
        raise RuntimeError(f"{what}: {status}")


def run(request, number):
    model = f"bench{number}"
    root = f"{model}.root"
    ode = f"{root}.ode"
    ok(Capi.newModel(model), "newModel")
    try:
        ok(Capi.addSystem(root, SYSTEM_WC), "root (weakly coupled)")
        ok(Capi.addSystem(ode, SYSTEM_SC), "ode (strongly coupled)")
        ok(Capi.setSolver(ode, SOLVER_CVODE), "CVODE")
        ok(Capi.setTolerance(ode, request["rtol"]), "tolerance")
        ok(Capi.setVariableStepSize(ode, 1e-6, 1e-12, request["step"]), "steps")
        ok(Capi.addSubModel(f"{ode}.m", request["fmu"]), "FMU")
        ok(Capi.setFixedStepSize(root, request["step"]), "output interval")
        ok(Capi.setResultFile(model, request["out"]), "result file")
        ok(Capi.removeSignalsFromResults(model, ".*"), "signals")
        for name in request["outputs"]:
            ok(Capi.addSignalsToResults(model, re.escape(f"{ode}.m.{name}")), name)
        ok(Capi.setStopTime(model, request["stop"]), "stop time")
        for name, value in request.get("parameters", {}).items():
            ok(Capi.setReal(f"{ode}.m.{name}", value), name)
        ok(Capi.instantiate(model), "instantiate")
        ok(Capi.initialize(model), "initialize")
        started = time.perf_counter()
        ok(Capi.simulate(model), "simulate")
        seconds = time.perf_counter() - started
        ok(Capi.terminate(model), "terminate")
        return {"seconds": seconds}
    finally:
        Capi.delete(model)


def main():
    ok(Capi.setCommandLineOption("--suppressPath=true"), "options")
    ok(Capi.setTempDirectory(tempfile.mkdtemp()), "temp directory")
    Capi.setLoggingLevel(0)
    ok(Capi.setLogFile(os.devnull), "log file")
    for number, line in enumerate(sys.stdin):
        try:
            answer = run(json.loads(line), number)
        except Exception as e:  # the worker reports and waits for the next request
            answer = {"error": str(e)}
        print(ANSWER + json.dumps(answer), flush=True)


if __name__ == "__main__":
    main()
