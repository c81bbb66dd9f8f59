"""The example measurements in measurements/ are what their scripts write: re-running a
script reproduces the shipped CSV, and it never overwrites a file unasked.

Both base scenes ask for method auto at tolerance 1e-3 on v_g, whose setting comes from
the packaged cost model: when the model is re-measured the simulated delays and peaks may
move within that tolerance (the noise, drawn from a fixed seed, does not), never more."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("script, csv", [("make_example_measurements.py", "example_synthetic.csv"),
                                         ("make_example_restitution.py", "example_restitution.csv")])
def test_example_data_is_reproduced_and_never_overwritten(script, csv, tmp_path):
    rtol = 1e-3
    out = tmp_path / csv
    run = lambda *a: subprocess.run([sys.executable, str(REPO / "scripts" / script), *a],  # noqa: E731
                                    capture_output=True, text=True, cwd=tmp_path)
    p = run("--out", str(out))
    assert p.returncode == 0, p.stderr
    shipped = REPO / "measurements" / csv
    a, b = pd.read_csv(out, comment="#"), pd.read_csv(shipped, comment="#")
    assert out.read_text().splitlines()[:2] == shipped.read_text().splitlines()[:2]
    pd.testing.assert_frame_equal(a, b, check_exact=False, rtol=rtol, atol=0.0)
    out.write_text("kept\n")
    p = run("--out", str(out))
    assert p.returncode == 2 and out.read_text() == "kept\n"
    assert p.stderr.count("\n") == 1 and "--force" in p.stderr and "Traceback" not in p.stderr
