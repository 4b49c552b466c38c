"""`import sim` stays light: the CLI's parser, the surrogate and the search read designs, spaces
and metric names through it without paying for the FE stack (issue: instant CLI start)."""

from __future__ import annotations

import json
import subprocess
import sys

HEAVY = ("torch", "matplotlib", "scipy", "skfem", "triangle", "qdldl", "optuna")


def _loaded_after(statement: str) -> list[str]:
    code = f"import sys, json; {statement}; print(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_import_sim_loads_no_heavy_package():
    loaded = _loaded_after("import sim; sim.SimOptions(); sim.load_design")
    heavy = [m for m in loaded if m.split(".")[0] in HEAVY]
    assert heavy == [], heavy


def test_reading_a_design_and_the_default_space_stays_light():
    loaded = _loaded_after(
        "from sim.space import load_space; from sim import homogeneous_design; "
        "load_space(); homogeneous_design('silicone_gls40')"
    )
    heavy = sorted({m.split(".")[0] for m in loaded} & set(HEAVY))
    assert heavy == [], heavy
