"""Run under `mpirun -n 2` by tests/test_distributed.py: the distributed offline stage of the penalty
ROM (jointfem.fem.distributed) with every array it moves between ranks recorded, then the same
model's replicated offline stage recorded the same way; rank 0 writes what the test compares."""
import json
import sys

import numpy as np

from jointfem import linalg
from jointfem.analysis.frf import solve_at
from jointfem.fem.continuum import create_continuum
from jointfem.fem.distributed import create_distributed
from jointfem.harmonics import Harmonics
from jointfem.rom.common import RomOptions
from jointfem.rom.penalty import PenaltyROM


def main(out: str, size: float, force: float, omegas: list[float]) -> None:
    from mpi4py import MPI

    sys.path.insert(0, "tests")
    from test_distributed import lap_spec

    comm = MPI.COMM_WORLD
    spec = lap_spec(size, force)
    with linalg.gather_audit() as audit:
        model = create_distributed(spec)
        rom = PenaltyROM(None, RomOptions(modes=10), distributed=model)
    rows = model.rows
    result = {"ranks": comm.size, "n": model.n, "free_dofs": model.num_dofs, "rows": list(rows),
              "audit": audit, "frequencies": rom.natural_frequencies(10).tolist(),
              "linear": {}, "nonlinear": {}}
    w = np.array(omegas)
    for name, row in rom.structure.outputs.items():
        X = rom.structure.linear_response(w) @ row
        result["linear"][name] = [X.real.tolist(), X.imag.tolist()]
    h = Harmonics(3, 128)
    for omega in omegas:
        sol = solve_at(rom, omega, h)
        result["nonlinear"][str(omega)] = {"amplitudes": sol.amplitudes, "active": int(np.sum(sol.record.active)),
                                           "residual": sol.residual}
    # the replicated path, recorded the same way: the audit must see its n-sized gathers
    with linalg.gather_audit() as old:
        PenaltyROM(create_continuum(spec), RomOptions(modes=10))
    result["replicated_audit"] = old
    if comm.rank == 0:
        with open(out, "w") as f:
            json.dump(result, f)


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), [float(w) for w in sys.argv[4].split(",")])
