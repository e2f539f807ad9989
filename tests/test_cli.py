"""``jointfem frf`` writes files a user can open, with the promised contents."""
import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from jointfem.results import load_branch

ROOT = Path(__file__).resolve().parents[1]


def test_frf_writes_csv_npz_json_png(tmp_path):
    out = tmp_path / "sdof"
    r = subprocess.run([sys.executable, "-m", "jointfem", "frf", str(ROOT / "demos" / "sdof_jenkins.toml"),
                        "--out", str(out), "--harmonics", "5", "--samples", "128"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    with open(out / "frf.csv") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["omega_rad_s", "freq_Hz", "m.x_amp1_m", "m.x_halfp2p_m"]
    data = np.array(rows[1:], dtype=float)
    np.testing.assert_allclose(data[:, 1], data[:, 0] / (2 * np.pi))
    assert np.isfinite(data).all() and data[0, 0] == 0.5 and data[-1, 0] >= 2.0
    np.testing.assert_allclose(data[:, 3], data[:, 2], rtol=0.05)  # weakly nonlinear: close to the 1st harmonic
    b = load_branch(out / "branch.npz")
    assert b["U"].shape == (data.shape[0], 11) and int(b["H"]) == 5 and int(b["N"]) == 128
    assert b["states"].shape == (data.shape[0], 128, 1)
    assert set(np.unique(b["states"])) <= {0, 1, 2} and (b["states"] == 1).any()
    # every point's achieved residual is recorded, and none is above the kink tolerance
    assert b["residual"].shape == (data.shape[0],) and b["residual"].max() <= 1e-8
    s = json.loads((out / "summary.json").read_text())
    for key in ("scene", "method", "model", "rom", "num_points", "newton_iterations_total", "wall_s", "peaks"):
        assert key in s
    assert s["harmonics"] == 5 and s["samples"] == 128 and s["num_points"] == data.shape[0]
    pk = s["peaks"]["m.x"]
    assert 1.3 < pk["omega_rad_s"] < 1.45 and pk["freq_Hz"] == pk["omega_rad_s"] / (2 * np.pi)
    png = (out / "frf.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
