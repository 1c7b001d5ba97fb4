"""The README's code runs, and its Quick start is what .ci/run executes."""

import re
import subprocess
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()


def test_readme_python_example_runs():
    blocks = re.findall(r"```python\n(.*?)```", README, re.S)
    assert blocks
    ns = {}
    for code in blocks:
        exec(compile(code, "README.md", "exec"), ns)  # noqa: S102 - our own README
    r, rc = ns["r"], ns["rc"]
    np.testing.assert_array_equal(r.hit, rc.hit)
    assert rc.contact.shape == (len(r.hit), 3)
    assert np.isnan(rc.contact[~rc.hit]).all() and np.isfinite(rc.contact[rc.hit]).all()
    # The signed distance agrees with the hits where collide must be sure (collide may report a hit
    # for a gap up to 2 tol, its touching band).
    sd, w = ns["sd"], ns["w"]
    sure = np.abs(sd.distance) > 2 * sd.tol
    np.testing.assert_array_equal(sd.status[sure] < 0, r.hit[: len(sd)][sure])
    np.testing.assert_allclose(w.point_b - w.point_a, w.distance[:, None] * w.normal, atol=1e-12)


def test_quick_start_has_two_commands_and_ci_reads_the_second():
    block = re.search(r"## Quick start.*?```bash\n(.*?)```", README, re.S).group(1).strip().splitlines()
    assert len(block) == 2
    assert "prismbatch reproduce --quick" in block[0] and "pytest" in block[1]
    # .ci/run extracts the test command with the same awk program: run that part.
    awk = r"awk '/^## Quick start/{f=1} f && /^```/{n++; next} f && n==1 {print}' README.md | sed -n 2p"
    out = subprocess.run(["bash", "-c", awk], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()
    assert out == block[1]
    assert awk.split(" | ")[0] in (ROOT / ".ci" / "run").read_text()
