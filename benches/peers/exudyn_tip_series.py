"""Exudyn's tip x over the run of the peers' stiff chain (index-3
generalized-α, fixed step), sampled every DT seconds, beside its CPU
seconds: the error over the run, not only at t = 0.1 s (docs/radau.md,
"The error over the run"). Uses exudyn_chain.py and chain_model.py from
MBSOLVE_PEERS (default ../shared/peers beside the repository).

    python exudyn_tip_series.py N H DT     -> one JSON line: h, cpu, t, tip_x
"""
import json
import os
import sys
import time

root = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.environ.get("MBSOLVE_PEERS", os.path.join(root, "..", "..", "..", "shared", "peers")))
import exudyn as exu  # noqa: E402
from exudyn.itemInterface import SensorBody  # noqa: E402
import exudyn_chain as ec  # noqa: E402


def main():
    n, h, dt = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
    mbs, bodies, p = ec.build(n)
    sensor = mbs.AddSensor(SensorBody(bodyNumber=bodies[-1], localPosition=[0, -p["ls"] / 2, 0],
                                      storeInternal=True, writeToFile=False,
                                      outputVariableType=exu.OutputVariableType.Position))
    mbs.Assemble()
    steps = int(round(ec.cm.T_END / h))
    s = ec.settings(h, steps, exu.LinearSolverType.EigenSparse)
    s.solution.sensors.writePeriod = dt
    s.solution.sensors.active = True
    solver_type = ec.VARIANTS["ga-sparse"][0]
    c0 = time.process_time()
    exu.SolveDynamic(mbs, s, solverType=solver_type)
    cpu = time.process_time() - c0
    data = mbs.GetSensorStoredData(sensor)
    print(json.dumps(dict(peer="exudyn", N=n, h=h, cpu=cpu, t=[float(r[0]) for r in data],
                          tip_x=[float(r[1]) for r in data])))


if __name__ == "__main__":
    main()
