"""examples/ab_figure.py runs end to end (small settings) and writes its table."""

import csv
import subprocess
import sys


def test_ab_figure_example(root, tmp_path):
    out = tmp_path / "ab"
    subprocess.run([sys.executable, str(root / "examples" / "ab_figure.py"), "--resolution", "16x16",
                    "--reference-spp", "64", "--budgets", "16,32", "-o", str(out)], check=True)
    rows = list(csv.DictReader(open(out.with_suffix(".csv"))))
    assert [(r["integrator"], r["spp"]) for r in rows] == [
        ("directlighting", "16"), ("directlighting", "32"), ("ltc", "16"), ("ltc", "32")]
    assert all(float(r["rmse"]) > 0 and float(r["seconds"]) > 0 for r in rows)
