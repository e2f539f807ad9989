"""The three systems of the peer comparison, as plain data that both sides read: jointfem (its own
venv) and pyHarm (benchmarks/peer/.venv-pyharm).  Nothing here imports either code.

Each case: point masses (1 kg) with DOFs x, y, z; springs and dampers to ground or between DOFs;
Jenkins pairs to ground (tangential axes, an optional normal axis); cosine forces; the swept range
(rad/s); H, N and the Newton tolerance, the same on both sides; and the output DOF whose first
harmonic is compared.

Normal contact: pyHarm's Penalty3D with N0 > 0 applies k_n x to the structure while in contact and
nothing when open, so its normal force jumps by N0 at separation; jointfem's pair (and the paper's)
keeps the balanced preload, so its force is continuous.  The two laws agree only for N0 = 0, which
the 2-DOF separation case therefore uses (N = k_n g in compression, open otherwise: the joint opens
every cycle and the normal load varies from 0 to its peak).
"""
from __future__ import annotations


def sdof() -> dict:
    """The SDOF Jenkins oscillator of demos/sdof_jenkins.toml: m = k = kt = mu N0 = 1, c = 0.02."""
    return {
        "name": "SDOF Jenkins", "dofs": {"m": ["x"]}, "springs": [["m.x", "ground", 1.0]],
        "dampers": [["m.x", "ground", 0.02]],
        "jenkins": [{"node": "m", "tangential": ["x"], "normal": None, "kt": 1.0, "kn": 0.0, "mu": 1.0, "N0": 1.0}],
        "forces": [["m.x", 0.2]], "omega": [0.5, 2.0], "H": 7, "N": 256, "tol": 1e-6, "output": "m.x",
        "ds_max_pyharm": 0.1,
    }


def separation() -> dict:
    """One mass, tangential x and y (2D friction) and normal z, one 3D pair to ground with N0 = 0:
    x and z are forced; the pair slips, sticks and opens within each period."""
    return {
        "name": "2-DOF normal load and separation (3D pair)", "dofs": {"m": ["x", "y", "z"]},
        "springs": [["m.x", "ground", 1.0], ["m.y", "ground", 1.0], ["m.z", "ground", 3.0]],
        "dampers": [["m.x", "ground", 0.05], ["m.y", "ground", 0.05], ["m.z", "ground", 0.05]],
        "jenkins": [{"node": "m", "tangential": ["x", "y"], "normal": "z", "kt": 1.0, "kn": 1.0, "mu": 0.5,
                     "N0": 0.0}],
        "forces": [["m.x", 0.3], ["m.z", 0.8]], "omega": [0.8, 2.4], "H": 7, "N": 256, "tol": 1e-6,
        "output": "m.x", "ds_max_pyharm": 0.1,
    }


def chain(n: int = 20) -> dict:
    """n masses in a chain (k = 1 to the left, the first to ground), a Jenkins pair from every mass
    to ground (kt = 0.05, mu N0 = 0.005), c = 0.01 to ground, the last mass forced with 0.01 N;
    0.1-0.4 rad/s holds the first two stuck modes (0.236 and 0.320 rad/s for n = 20); the pairs
    near the free end slip around the first peak.  pyHarm's ds_max (raw units) is 0.02 here: at 0.1
    it takes 33 points and places its highest point 0.3 % off the peak frequency; at 0.02 it takes
    about as many points as jointfem (150 against 131) and resolves the peak."""
    springs = [["m0.x", "ground", 1.0]] + [[f"m{i - 1}.x", f"m{i}.x", 1.0] for i in range(1, n)]
    return {
        "name": f"chain of {n} masses, {n} Jenkins pairs", "dofs": {f"m{i}": ["x"] for i in range(n)},
        "springs": springs, "dampers": [[f"m{i}.x", "ground", 0.01] for i in range(n)],
        "jenkins": [{"node": f"m{i}", "tangential": ["x"], "normal": None, "kt": 0.05, "kn": 0.0, "mu": 1.0,
                     "N0": 0.005} for i in range(n)],
        "forces": [[f"m{n - 1}.x", 0.01]], "omega": [0.1, 0.4], "H": 5, "N": 128, "tol": 1e-6,
        "output": f"m{n - 1}.x", "ds_max_pyharm": 0.02,
    }


CASES = {"sdof": sdof, "separation": separation, "chain": chain}
