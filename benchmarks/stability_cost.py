"""What Hill's stability costs a sweep, as ratios measured in one process (issue 46, item 3).

    python benchmarks/stability_cost.py demos/beam2d.toml full
    python benchmarks/stability_cost.py demos/lap2d.toml penalty

Runs the scene's sweep five ways, twice each, interleaved so that they share the machine's load:
stability off; on as the sweep computes it; on without the contact laws' memory (Hill's matrix as it
is, before 2026-12-07 evening; the older ways too); on with Arnoldi's shift and radius of before 2026-12-07
(sigma = 1e-3 omega, radius 1.2 omega); on as it was computed before 2026-12-06 (every point on its
own: dense up to 1600 first-order unknowns, else Arnoldi asking 24 eigenvalues then twice as many,
ARPACK tolerance 1e-12, a Krylov space twice the count, the shift and radius of then).  Prints the
online times, the ratios with over without, and how far the "on" runs' largest real parts and
verdicts are apart from the first.
"""
import argparse

import numpy as np

from jointfem.analysis import stability as st
from jointfem.app import solve_scene
from jointfem.rom import METHODS
from jointfem.scene import load_scene


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", help="scene file (TOML)")
    ap.add_argument("method", nargs="?", default="full", choices=METHODS, help="default full")
    args = ap.parse_args(argv)
    scene = load_scene(args.scene)
    method = args.method
    now = (st.FIRST, st.ARNOLDI_TOL, st.DENSE_LIMIT, st.NCV_FACTOR, st.ExponentTracker.__call__, st.SHIFT, st.RADIUS,
           st.MEMORY_CANDIDATES)

    def old_call(self, x, lam, evaluation):  # every point on its own: dense or not by its size, 24 asked first
        return st._leading(self.problem, x, lam, evaluation, None, 24, False)[::2]

    ways = {"off": now, "on": now, "on, without the memory": now[:7] + (0,),
            "on, shift of 2026-12-06": now[:5] + (1e-3, 1.2, 0),
            "on, before 2026-12-06": (24, 1e-12, 1600, 2.0, old_call, 1e-3, 1.2, 0)}
    online, last = {}, {}
    for rep in range(2):
        for way, settings in ways.items():
            (st.FIRST, st.ARNOLDI_TOL, st.DENSE_LIMIT, st.NCV_FACTOR, st.ExponentTracker.__call__, st.SHIFT,
             st.RADIUS, st.MEMORY_CANDIDATES) = settings
            frf = solve_scene(scene, stability="off" if way == "off" else "on", method=method).frf
            online.setdefault(way, []).append(frf.info["time_online_s"])
            last[way] = frf
            print(f"{rep} stability {way}: online {frf.info['time_online_s']:.1f} s, "
                  f"{frf.omega.size} points, {frf.info['stability']}", flush=True)
    (st.FIRST, st.ARNOLDI_TOL, st.DENSE_LIMIT, st.NCV_FACTOR, st.ExponentTracker.__call__, st.SHIFT, st.RADIUS,
     st.MEMORY_CANDIDATES) = now
    off = np.mean(online["off"])
    print("ratio with/without: " + ", ".join(f"{w} {np.mean(t) / off:.2f}" for w, t in online.items() if w != "off"))
    a = last["on"]
    for way in list(ways)[2:]:
        b = last[way]
        if a.omega.size == b.omega.size:
            d = np.abs(a.info["arrays"]["floquet_max_real"] - b.info["arrays"]["floquet_max_real"]) / a.omega
            print(f"{way}: largest real parts apart by at most {d.max():.2e} omega; verdicts differ at "
                  f"{int((a.stable != b.stable).sum())} points")


if __name__ == "__main__":
    main()
