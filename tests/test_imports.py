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
        "from sim.design import load_space; from sim import homogeneous_design; "
        "load_space(); homogeneous_design('silicone_gls40')"
    )
    heavy = sorted({m.split(".")[0] for m in loaded} & set(HEAVY))
    assert heavy == [], heavy


def test_the_metric_registry_and_the_options_stay_light():
    """The surrogate reads metric names and the options from their own modules (issue 16)."""
    loaded = _loaded_after(
        "from sim.metrics import METRICS, diagnostic_names; from sim.options import SimOptions; "
        "diagnostic_names(); SimOptions().with_mesh_refined(2)"
    )
    heavy = sorted({m.split(".")[0] for m in loaded} & set(HEAVY))
    assert heavy == [], heavy


#: what the CLI's parser and ``--help`` must not pay for (issue 15: instant start)
NOT_FOR_THE_PARSER = ("torch", "matplotlib", "optuna", "scipy", "skfem", "surrogate")


def _loaded_after_cli(*runs: list[str], top_level: bool = True) -> set[str]:
    """Packages (top-level ones, or every module) loaded by ``fingertip ARGV`` for each ARGV of
    ``runs`` in turn, in one fresh process (the output swallowed)."""
    statement = (
        "import contextlib, io; from explore.cli import main\n"
        f"for argv in {[list(r) for r in runs]!r}:\n"
        "    with contextlib.redirect_stdout(io.StringIO()):\n"
        "        try:\n"
        "            main(argv)\n"
        "        except SystemExit:\n"
        "            pass\n"
    )
    code = f"import sys, json\n{statement}print(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return {m.split(".")[0] if top_level else m for m in json.loads(out.stdout)}


def test_cli_parser_builds_without_heavy_packages():
    loaded = _loaded_after("from explore.cli import build_parser; build_parser()")
    assert sorted({m.split(".")[0] for m in loaded} & set(NOT_FOR_THE_PARSER)) == []


def test_help_of_fingertip_and_every_subcommand_stays_light():
    from explore.cli import _SUBCOMMANDS

    commands = list(_SUBCOMMANDS)
    loaded = _loaded_after_cli(["--help"], *([c, "--help"] for c in commands))
    assert sorted(loaded & set(NOT_FOR_THE_PARSER)) == []


def test_fingertip_help_runs_and_lists_every_subcommand():
    out = subprocess.run(
        [sys.executable, "-m", "explore.cli", "--help"], capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    for command in ("simulate", "sweep", "train", "predict", "optimize", "run", "report"):
        assert command in out.stdout


def test_simulate_never_loads_the_surrogate_or_torch():
    loaded = _loaded_after_cli(["simulate", "--material", "silicone_gls40", "--protocol", "plate"])
    assert "qdldl" in loaded  # it did simulate
    assert sorted(loaded & {"torch", "surrogate", "optuna", "matplotlib"}) == []


def test_simulate_skips_the_modules_it_does_not_need():
    """scipy.spatial (a KD-tree for the mesh size) costs ~0.1 s of a one-protocol simulate's
    start-up, scikit-fem (with scipy.sparse.linalg and csgraph) ~0.09 s; both are replaced by
    numpy (tests/test_fe.py, tests/test_p2.py). scipy.sparse stays: qdldl imports it; so does
    scipy.special, for ``exprel`` (a numpy copy of it differed by an ulp on some CPUs)."""
    loaded = _loaded_after_cli(
        ["simulate", "--protocol", "plate", "docs/designs/slow_creep.toml"], top_level=False
    )
    assert "qdldl" in loaded  # it did simulate
    unneeded = ("scipy.spatial", "scipy.sparse.linalg", "scipy.sparse.csgraph")
    assert sorted(m for m in loaded if m.startswith(unneeded) or m.split(".")[0] == "skfem") == []
    # nor what only the other subcommands' options need (the parser builds simulate's alone)
    others = ("explore._config", "explore._search", "sim.materials.fit", "sim.sweep")
    assert sorted(m for m in loaded if m.startswith(others)) == []
