"""fmpy's cost of the loop the master benchmark measures: setReal(u), doStep, getReal(y) on
one LinearSystem instance. Prints the median nanoseconds per step over several batches.

Usage: python tests/bench/fmpy_loop.py <LinearSystem.fmu> <steps per batch> <batches>
"""

import sys
import time

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave


def main(path, steps, batches):
    md = read_model_description(path)
    unzip = extract(path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    u, y = [vr["u[1]"]], [vr["y[1]"]]
    t, h = 0.0, 0.01
    samples = []
    for _ in range(batches):
        start = time.perf_counter_ns()
        for k in range(steps):
            fmu.setReal(u, [0.5])
            fmu.doStep(t, h)
            fmu.getReal(y)
            t += h
        samples.append((time.perf_counter_ns() - start) / steps)
    fmu.terminate()
    fmu.freeInstance()
    samples.sort()
    print(samples[len(samples) // 2])


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
