"""Run one case of benchmarks/peer/cases.py with pyHarm (SAFRAN, Apache-2.0), inside its own venv:

    benchmarks/peer/.venv-pyharm/bin/python benchmarks/peer/run_pyharm.py sdof --repeats 3 --out r.json

Writes JSON: omega and the first-harmonic amplitude of the case's output DOF at every accepted
point, the wall time of each whole sweep (the first, which compiles numba/jax kernels, is a warm-up
reported apart), the point count, pyHarm's version, and where a further, profiled sweep spent
its time.  Uses pyHarm's public input dictionary only.

Mapping: one "onlydofs" substructure with a node per mass and 1 or 3 DOFs per node; a mass is a
GOElement with dto = 2; springs/dampers are LinearSpring/LinearDamper; a pair with one tangential
axis is a Jenkins element, a pair with two tangential axes and a normal one is a Penalty3D element
(dirs ordered normal, tangential 1, tangential 2); forces are CosinusForcing.  The solver is
pyHarm's NewtonRaphson with tol_residual = tol * max|F| (the 2-norm, at least as strict as
jointfem's max-norm test max|R| <= tol max|F|), with pyHarm's tangent predictor, arc-length
corrector and step acceptance rule.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import logging
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from cases import CASES  # noqa: E402

AXES = "xyz"


def build_input(case: dict) -> tuple[dict, dict]:
    nodes = list(case["dofs"])
    three = any(len(d) > 1 or d[0] != "x" for d in case["dofs"].values())
    ndofs = 3 if three else 1

    def where(dof: str):
        node, axis = dof.split(".")
        return nodes.index(node), (AXES.index(axis) if three else 0)

    def link(a: str, b: str):
        ia, d = where(a)
        if b == "ground":
            return [["sub", [ia]], ["GROUND", [0]]], d
        ib, db = where(b)
        assert db == d, "links join the same axis"
        return [["sub", [ia]], ["sub", [ib]]], d

    conn = {}
    flipped = set()
    fmax = max(abs(a) for _, a in case["forces"])
    for i, (node, axes) in enumerate(case["dofs"].items()):
        for ax in axes:
            conn[f"mass_{node}_{ax}"] = {"type": "GOElement", "dto": 2, "xo": 1, "k": 1.0,
                                         "connect": [["sub", [i]], ["GROUND", [0]]], "dirs": [where(f"{node}.{ax}")[1]]}
    for kind, key in (("springs", "LinearSpring"), ("dampers", "LinearDamper")):
        for j, (a, b, v) in enumerate(case[kind]):
            c, d = link(a, b)
            conn[f"{kind}_{j}"] = {"type": key, "k": float(v), "connect": c, "dirs": [d]}
    for j, p in enumerate(case["jenkins"]):
        i = nodes.index(p["node"])
        c = [["sub", [i]], ["GROUND", [0]]]
        if p["normal"] is None:
            assert len(p["tangential"]) == 1
            conn[f"jenkins_{j}"] = {"type": "Jenkins", "k": p["kt"], "mu": p["mu"], "N0": p["N0"], "connect": c,
                                    "dirs": [where(f"{p['node']}.{p['tangential'][0]}")[1]]}
        else:
            # N0 = 0 in Penalty3D takes a branch whose friction law divides by a zero slip increment
            # while the pair is open (NaN in its jax Jacobian at the first point).  Its N0 > 0 branch
            # counts the normal gap positive when opening, and drops the preload when open; with
            # N0 = eps = 1e-9 max|F| that drop is negligible, and flipping the normal axis (its
            # forces change sign; masses, springs and dampers are symmetric) gives jointfem's law.
            assert len(p["tangential"]) == 2 and p["N0"] == 0.0, "Penalty3D matches jointfem only for N0 = 0"
            dirs = [where(f"{p['node']}.{ax}")[1] for ax in [p["normal"], *p["tangential"]]]
            flipped.add(f"{p['node']}.{p['normal']}")
            conn[f"penalty3d_{j}"] = {"type": "Penalty3D", "k_n": p["kn"], "k_t": p["kt"], "mu": p["mu"],
                                      "N0": 1e-9 * fmax, "g": 0.0, "connect": c, "dirs": dirs}
    for j, (dof, amp) in enumerate(case["forces"]):
        i, d = where(dof)
        sign = -1.0 if dof in flipped else 1.0
        conn[f"force_{j}"] = {"type": "CosinusForcing", "amp": sign * float(amp),
                              "connect": [["sub", [i]], ["GROUND", [0]]], "dirs": [d]}
    w0, w1 = case["omega"]
    data = {
        "system": {"type": "Base", "nh": case["H"], "nti": case["N"]},
        "substructures": {"sub": {"type": "onlydofs", "nnodes": len(nodes), "ndofs": ndofs}},
        "connectors": conn,
        "analysis": {"FRF": {"study": "frf", "puls_inf": w0, "puls_sup": w1, "puls_start": w0,
                             "ds0": case["ds_max_pyharm"] / 4, "ds_min": 1e-8, "ds_max": case["ds_max_pyharm"],
                             "solver": "NewtonRaphson",
                             "solver_options": {"tol_residual": case["tol"] * fmax, "tol_delta_x": 1e-6,
                                                "max_iter": 40},
                             "verbose": False}},
    }
    out = where(case["output"])
    return data, {"node": out[0], "dir": out[1], "ndofs": ndofs}


def run(case: dict) -> dict:
    import pyHarm

    data, out = build_input(case)
    with contextlib.redirect_stdout(io.StringIO()):
        t = time.perf_counter()  # the model set-up is timed, as on jointfem's side
        m = pyHarm.Maestro(json.loads(json.dumps(data)))
        m.operate()
        wall = time.perf_counter() - t
    sols = [s for s in m.nls["FRF"].SolList if getattr(s, "flag_accepted", False)]
    edf = m.system.expl_dofs
    sel = edf[(edf["node_num"] == out["node"]) & (edf["dof_num"] == out["dir"]) & (edf["harm"] == 1)]
    ic = int(sel[sel["cs"] == "c"].index[0])
    is_ = int(sel[sel["cs"] == "s"].index[0])
    X = np.array([s.x for s in sols])
    return {"wall_s": wall, "omega": X[:, -1].tolist(), "amp": np.hypot(X[:, ic], X[:, is_]).tolist(),
            "points": len(sols), "solutions_tried": len(m.nls["FRF"].SolList),
            "iterations": [int(getattr(s, "iter_numb", -1)) for s in sols]}


def profile_shares(case: dict) -> dict:
    """One extra, profiled sweep (not timed): the shares of pyHarm's run spent building the global
    Jacobian (System.Jacobian, all of it), in its per-element loops (ABCSystem._jacobian and
    _residual: every element, linear ones included, evaluated and scattered into a dense n x n
    array at every iteration), in the Jacobians of the friction elements themselves (Jenkins,
    Penalty3D), in Newton's dense linear solves (scipy.linalg.solve) and in the predictor's dense
    QR (scipy.linalg.qr)."""
    import cProfile
    import pstats

    prof = cProfile.Profile()
    prof.enable()
    run(case)
    prof.disable()
    st = pstats.Stats(prof)
    cum = dict.fromkeys(("global_jacobian", "element_loops", "friction_jacobians", "linear_solves", "predictor_qr"),
                        0.0)
    for (filename, _, name), (_, _, _, ct, _) in st.stats.items():
        f = filename.replace("\\", "/")
        if f.endswith("Systems/System.py") and name == "Jacobian":
            cum["global_jacobian"] += ct
        elif f.endswith("Systems/ABCSystem.py") and name in ("_jacobian", "_residual"):
            cum["element_loops"] += ct
        elif f.endswith(("/Jenkins.py", "/Penalty3D.py")) and name == "evalJacobian":
            cum["friction_jacobians"] += ct
        elif "scipy/linalg" in f and name == "solve":
            cum["linear_solves"] += ct
        elif "scipy/linalg" in f and name == "qr":
            cum["predictor_qr"] += ct
    return {k: v / st.total_tt for k, v in cum.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("case", choices=sorted(CASES))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    warnings.filterwarnings("ignore")
    logging.disable(logging.INFO)
    import pyHarm
    from importlib.metadata import version

    case = CASES[args.case]()
    warm = run(case)
    runs = [run(case) for _ in range(args.repeats)]
    res = runs[-1]
    res["profile"] = profile_shares(case)
    res.update(warmup_s=warm["wall_s"], walls_s=[r["wall_s"] for r in runs],
               median_s=statistics.median(r["wall_s"] for r in runs), pyharm=version("pyharm-os"),
               numpy=np.__version__, python=sys.version.split()[0], case=args.case)
    import jax
    import numba
    import scipy
    res.update(scipy=scipy.__version__, numba=numba.__version__, jax=jax.__version__)
    Path(args.out).write_text(json.dumps(res))
    print(f"{args.case}: {res['points']} points, median {res['median_s']:.3f} s (warm-up {warm['wall_s']:.1f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
