"""A tiny design space, fast options and a tiny trained surrogate shared by the tests."""

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: the shipped surrogate and its training sweep (config.json, table.csv.gz)
SHIPPED = REPO / "surrogate" / "pretrained" / "default"


def shipped_table_lines(n: int) -> list[str]:
    """The first ``n`` lines of the shipped training table (header included), as text lines
    ending in ``\\n`` (what ``Path.read_text`` gave when the table was shipped uncompressed)."""
    import gzip
    import itertools

    with gzip.open(SHIPPED / "table.csv.gz", "rt", encoding="utf-8") as fh:
        return list(itertools.islice(fh, n))


TINY = """
[geometry]
half_width_mm = { value = 5.84 }
height_mm = { value = 5.48 }
exponent = { value = 1.5 }
[layers]
count = { choice = [1, 2] }
[layers.skin]
thickness_mm = { low = 0.3, high = 1.0 }
material = { choice = ["silicone_gls40", "polyurethane_74_45"] }
[layers.core]
material = { choice = ["param"] }
mu0_MPa = { low = 0.02, high = 0.1, log = true }
alpha = { low = 2.0, high = 6.0 }
nu = { value = 0.47 }
g_total = { low = 0.1, high = 0.4 }
tau_s = { low = 0.1, high = 1.0, log = true }
"""
#: sweep options that keep a design at a few seconds: 3 taps whose periodic state is accepted
#: at a loose residual (0.5: polyurethane's 25 s term is at ~0.2 after 3 taps) and a 10 % error
#: estimate, so that the designs count as settled and are used for training; a 5 s wedge hold
FAST = [
    "--set", "tapping.max_taps=3",
    "--set", "tapping.residual_tol=0.5",
    "--set", "tapping.settle_tol=0.1",
    "--set", "wedge.hold_s=5",
]  # fmt: skip


def tiny_surrogate(root: Path, space_toml: str) -> Path:
    """A real FE sweep of ``space_toml`` (10 designs, ``FAST`` options) in ``root`` and a small
    surrogate trained on it by the CLI; the checkpoint's path."""
    import explore.cli

    (root / "space.toml").write_text(space_toml)
    sweep = root / "sweep"
    argv = ["sweep", root / "space.toml", "--n", "10", "--out", sweep, "--no-progress", *FAST]
    assert explore.cli.main([str(a) for a in argv]) == 0
    train = ["train", sweep, "--out", root / "model", "--max-epochs", "30", "--no-progress"]
    env = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, "-m", "explore.cli", *map(str, train)], cwd=REPO,
                          capture_output=True, text=True, timeout=600, env=env)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return root / "model" / "model.safetensors"
