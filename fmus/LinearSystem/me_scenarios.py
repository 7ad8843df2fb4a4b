"""Model Exchange scenarios of LinearSystem.fmu (n = 2, m = 1, p = 1) in continuous time without
noise (Model Exchange integrates dx/dt = A x + B u; with `continuous` = false it is refused):
fmpy's CVode (relative tolerance 1e-8) against the Co-Simulation FMU, whose step is the exact
matrix-exponential solution; no events."""

A = [[-0.5, 1.0], [-2.0, -0.3]]
B = [[0.0], [1.0]]
C = [[1.0, 0.5]]
D = [[0.2]]


def starts(u=0.0, x0=(0.0, 0.0)):
    """Start values: continuous, noise-free, the matrices above, x0 and the input u[1]."""
    values = {"continuous": True, "Q[1,1]": 0.0, "Q[2,2]": 0.0, "R[1,1]": 0.0,
              "x0[1]": x0[0], "x0[2]": x0[1], "u[1]": u}
    for name, m in [("A", A), ("B", B), ("C", C), ("D", D)]:
        for i, row in enumerate(m):
            for j, value in enumerate(row):
                values[f"{name}[{i + 1},{j + 1}]"] = value
    return values


SCENARIOS = [
    dict(name="step_response", start_values=starts(u=1.0), inputs=[(0.0, {"u[1]": 1.0})],
         stop_time=10.0, outputs=["x[1]", "x[2]", "y[1]"], output_interval=0.05,
         rtol_vs_cs=1e-6, event_times=[]),
    dict(name="free_response", start_values=starts(x0=(1.0, -0.5)),
         inputs=[(0.0, {"u[1]": 0.0})], stop_time=10.0, outputs=["x[1]", "x[2]", "y[1]"],
         output_interval=0.05, rtol_vs_cs=1e-6, event_times=[]),
]
