"""What Hill's stability costs a sweep, as ratios measured in one process (issue 46, item 3).

    python benchmarks/stability_cost.py demos/beam2d.toml full
    python benchmarks/stability_cost.py demos/lap2d.toml penalty

Runs the scene's sweep three ways, twice each, interleaved so that they share the machine's load:
stability off; on as the sweep computes it; on as it was computed before 2026-12-06 (every point on
its own: dense up to 1600 first-order unknowns, else Arnoldi asking 24 eigenvalues then twice as
many, ARPACK tolerance 1e-12, a Krylov space twice the count).  Prints the online times, the ratios
with over without, and how far the two "on" runs' largest real parts and verdicts are apart.
"""
import sys
import time

import numpy as np

from jointfem.analysis import stability as st
from jointfem.app import solve_scene
from jointfem.scene import load_scene


def main():
    scene = load_scene(sys.argv[1])
    method = sys.argv[2] if len(sys.argv) > 2 else "full"
    now = st.FIRST, st.ARNOLDI_TOL, st.DENSE_LIMIT, st.NCV_FACTOR, st.ExponentTracker.__call__

    def old_call(self, x, lam, evaluation):  # every point on its own: dense or not by its size, 24 asked first
        return st._leading(self.problem, x, lam, evaluation, None, 24)[0]

    online, last = {}, {}
    for rep in range(2):
        for mode, before in (("off", False), ("on", False), ("on", True)):
            (st.FIRST, st.ARNOLDI_TOL, st.DENSE_LIMIT, st.NCV_FACTOR,
             st.ExponentTracker.__call__) = (24, 1e-12, 1600, 2.0, old_call) if before else now
            frf = solve_scene(scene, stability=mode, method=method).frf
            online.setdefault((mode, before), []).append(frf.info["time_online_s"])
            last[(mode, before)] = frf
            print(f"{rep} stability {mode}{' (before)' if before else ''}: online {frf.info['time_online_s']:.1f} s, "
                  f"{frf.omega.size} points, {frf.info['stability']}", flush=True)
    off = np.mean(online[("off", False)])
    print(f"ratio with/without: now {np.mean(online[('on', False)]) / off:.2f}, "
          f"before {np.mean(online[('on', True)]) / off:.2f}")
    a, b = last[("on", False)], last[("on", True)]
    if a.omega.size == b.omega.size:
        d = np.abs(a.info["arrays"]["floquet_max_real"] - b.info["arrays"]["floquet_max_real"]) / a.omega
        print(f"largest real parts apart by at most {d.max():.2e} omega; verdicts differ at "
              f"{int((a.stable != b.stable).sum())} points")


if __name__ == "__main__":
    main()
