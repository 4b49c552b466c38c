"""A search run's answers as design files, the answers by name on the command line, the
report's verdict and the commands' --version and --help (issue 35, items 3, 4 and 6).

A small run folder is written by hand here (no search, no FE): summary.json with a best, a foam
and a buildable answer and no gel one, confirmations.json with one design beyond the validity
limits, config.json and meta.json as a run writes them. The real simulations use
``--protocol plate`` only (well under a second)."""

from __future__ import annotations

import json
import math
import tomllib
from importlib import metadata
from pathlib import Path

import pytest

import explore._report
from explore._pipeline import write_answer_files
from explore._run_folder import answer_path
from explore._summary import ANSWER_KINDS, layer_materials
from explore._types import Candidate, Confirmation
from explore.cli import ANSWER_NAMES, build_parser, main
from sim.design import design_from_dict, design_to_toml, load_design, load_space, point_to_design
from sim.materials import CATALOGUE

ERROR_PREFIX = "fingertip: error: "
TARGETS = {"disp_at_1N_mm": 1.83, "disp_at_4N_mm": 2.91, "hysteresis_Nmm": 2.26}
#: the points of the answers (in the shipped space: the shipped surrogate predicts them)
BEST = {
    "geometry.half_width_mm": 6.7, "geometry.height_mm": 6.4, "geometry.exponent": 1.35,
    "layers.count": 2, "skin.material": "platsil_gel_10_marechal", "skin.thickness_mm": 0.4,
    "core.material": "gel", "core.mu0_MPa": 0.0105, "core.alpha": 3.8, "core.g_total": 0.555,
    "core.tau_s": 0.0408,
}  # fmt: skip
FOAM = {
    "geometry.half_width_mm": 7.8, "geometry.height_mm": 6.2, "geometry.exponent": 2.0,
    "layers.count": 2, "skin.material": "gel", "skin.thickness_mm": 0.26, "skin.mu0_MPa": 0.027,
    "skin.alpha": 2.5, "skin.g_total": 0.09, "skin.tau_s": 1.76, "core.material": "foam",
    "core.mu0_MPa": 0.023, "core.alpha": 1.9, "core.nu": 0.24, "core.g_total": 0.47,
    "core.tau_s": 0.056,
}  # fmt: skip
BUILDABLE = {
    "geometry.half_width_mm": 5.1, "geometry.height_mm": 6.2, "geometry.exponent": 1.47,
    "layers.count": 2, "skin.material": "polyurethane_74_45", "skin.thickness_mm": 0.99,
    "core.material": "ecoflex_0010_dawood",
}  # fmt: skip
#: FE displacements from touch, from the top (mm), hysteresis (N mm), sag (mm), tapping strain
FE = {
    "best": (1.21, 2.09, 1.38, 2.25, 1.33, 0.167, 0.598),
    "foam": (0.78, 1.95, 1.0, 2.18, 1.73, 0.222, 0.587),
    "buildable": (1.04, 1.88, 1.14, 1.98, 0.404, 0.101, 0.45),
}


def _metrics(values: tuple[float, ...]) -> dict[str, float]:
    touch1, touch4, top1, top4, hyst, sag, _ = values
    return {
        "disp_at_1N_mm": top1, "disp_at_4N_mm": top4, "disp_at_1N_from_touch_mm": touch1,
        "disp_at_4N_from_touch_mm": touch4, "hysteresis_Nmm": hyst, "sag_mm": sag,
        "plate_force_at_1mm_N": 0.9, "wedge_peak_force_N": 0.26,
    }  # fmt: skip


def _answer(kind: str, point: dict, rnd: int) -> dict:
    values = FE[kind]
    fe = _metrics(values)
    errors = {
        "disp_at_1N_mm": values[0] / TARGETS["disp_at_1N_mm"] - 1,
        "disp_at_4N_mm": values[1] / TARGETS["disp_at_4N_mm"] - 1,
        "hysteresis_Nmm": values[4] / TARGETS["hysteresis_Nmm"] - 1,
    }
    return {
        "design": point_to_design(point, CATALOGUE).to_dict(),
        "point": point,
        "family": "mixed",
        "search": "continuous",
        "reason": kind,
        "round": rnd,
        "predicted": {},
        "fe_metrics": fe,
        "fe_score": 0.3 + 0.1 * rnd,
        "readings": {
            "from_undeformed_top": {"disp_at_1N_mm": values[2], "disp_at_4N_mm": values[3]},
            "from_first_touch": {"disp_at_1N_mm": values[0], "disp_at_4N_mm": values[1]},
            "sag_mm": values[5],
        },
        "errors_vs_targets": errors,
        "within_tolerance": {m: abs(e) <= 0.05 for m, e in errors.items()},
        "credible": True,
        "diagnostics": {
            "valid": True,
            "settled": True,
            "tapping_max_compressive_log_strain": values[6],
            "tapping_min_J": 0.98,
            "plate_max_compressive_log_strain": 0.28,
            "plate_min_J": 0.99,
        },
        "fe_record": f"fe/records/{kind}.json",
    }


def _confirmations() -> list[dict]:
    out = []
    for k, (kind, point) in enumerate((("best", BEST), ("foam", FOAM), ("buildable", BUILDABLE))):
        cand = Candidate(point, kind, 0, k, "continuous", 0.3, {}, True, 0.01)
        fe = _metrics(FE[kind])
        rel = {m: 0.01 * (k + 1) for m in fe}
        diag = {"valid": True, "settled": True}
        out.append(Confirmation(cand, kind, "ok", "", fe, 0.3 + 0.1 * k, rel, {}, diag))
    cand = Candidate(BEST, "gel", 0, 9, "gel", 0.4, {}, True, 0.01)
    invalid = {
        "valid": False, "stopped": "tapping", "settled": None,
        "violations": "compressive log strain 0.61 > 0.60 (tapping)",
        "tapping_max_compressive_log_strain": 0.61,
    }  # fmt: skip
    none = dict.fromkeys(_metrics(FE["best"]))
    out.append(Confirmation(cand, "invalid", "ok", "", none, math.inf, {}, {}, invalid))
    cand = Candidate(BEST, "best", 0, 10, "continuous", 0.4, {}, True, 0.01)
    out.append(Confirmation(cand, "failed", "failed", "tapping: Newton stalled", {}, math.inf))
    return [c.to_json() for c in out]


@pytest.fixture
def run(tmp_path: Path) -> Path:
    """A finished search run folder as a run writes it (no FE, no study)."""
    folder = tmp_path / "main"
    folder.mkdir()
    answers = {
        "best": _answer("best", BEST, 2),
        "gel": None,
        "foam": _answer("foam", FOAM, 1),
        "buildable": _answer("buildable", BUILDABLE, 2),
    }
    summary = {"answers": answers, "targets": TARGETS, "tolerance": 0.05, "rounds": [],
               "notes": []}  # fmt: skip
    (folder / "summary.json").write_text(json.dumps(summary))
    (folder / "confirmations.json").write_text(json.dumps(_confirmations()))
    config = {
        "storage": str(folder / "study.log"), "targets": TARGETS,
        "displacement_reading": "from_first_touch", "max_sag_mm": 0.37, "tolerance": 0.05,
        "sim_options": {"tapping": {"max_taps": 3}},
    }  # fmt: skip
    (folder / "config.json").write_text(json.dumps(config))
    meta = {"kind": "optimize", "command": "/venv/bin/fingertip run --out runs/main"}
    (folder / "meta.json").write_text(json.dumps(meta))
    return folder


def _one_error_line(err: str, *words: str) -> str:
    assert "Traceback" not in err
    (line,) = err.splitlines()
    assert line.startswith(ERROR_PREFIX) and all(w in line for w in words), line
    return line


# ---------------------------------------------------------------------------- design TOML
DESIGNS = {
    "catalogue and gel": point_to_design(BEST, CATALOGUE).to_dict(),
    "foam core": point_to_design(FOAM, CATALOGUE).to_dict(),
    "three layers, user material": {
        "geometry": {"half_width_mm": 6.0, "height_mm": 5.5, "exponent": 1.5},
        "layers": [
            {"thickness_mm": 0.3, "material": "silicone_gls40"},
            {
                "thickness_mm": 0.5,
                "material": {
                    "model": "yeoh",
                    "c10_MPa": 0.01,
                    "c20_MPa": -0.001,
                    "c30_MPa": 0.0002,
                    "nu": 0.49,
                    "moduli": "long_term",
                    "name": 'my gel "A"',
                    "source": "bench test\nline 2 \\ tab\t",
                    "provenance": {
                        "r2": 0.99,
                        "fit by": "fingertip fit-material",
                        "modes": ["uniaxial", "planar"],
                    },
                },
            },
            {"material": "ecoflex_0010_dawood"},
        ],
    },
}


@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_an_answer_toml_reads_back_to_the_same_design(name: str, tmp_path: Path) -> None:
    """design dict -> TOML -> the same dict, bit for bit (floats by repr), and a design that
    ``load_design`` builds to the same dict again, whatever the comments say."""
    data = DESIGNS[name]
    header = ['answer "best": quotes " and \\ and a control character \x07', "", "second"]
    notes = {"layers[1]": ["core: a note"], "layers[1].material": ["on the table"]}
    text = design_to_toml(data, header, notes)
    assert tomllib.loads(text) == data
    path = tmp_path / "d.toml"
    path.write_text(text)
    assert load_design(path).to_dict() == design_from_dict(data).to_dict()
    assert text.startswith('# answer "best"') and text.endswith("\n")


def test_a_design_written_twice_is_the_same_text() -> None:
    design = design_from_dict(DESIGNS["foam core"])
    assert design_to_toml(design) == design_to_toml(design.to_dict())


# ---------------------------------------------------------------------------- answer files
def test_every_answer_of_a_run_is_a_design_file(run: Path) -> None:
    stale = answer_path(run, "gel")
    stale.parent.mkdir()
    stale.write_text("# an answer the run no longer has\n")
    paths = write_answer_files(run)
    assert paths == [answer_path(run, k) for k in ("best", "foam", "buildable")]
    assert not stale.exists()  # no gel answer: no gel file
    summary = json.loads((run / "summary.json").read_text())
    for path in paths:
        kind = path.stem
        assert load_design(path).to_dict() == summary["answers"][kind]["design"]
        text = path.read_text()
        head = text.split("\n\n")[0]
        assert f'fingertip answer "{kind}" of the search run "main"' in head
        assert f"FE score {summary['answers'][kind]['fe_score']:.3g}" in head
        assert "made by: fingertip run --out runs/main" in head
        # the run's FE options are not the defaults: the command that reproduces them
        assert "fingertip simulate THIS_FILE --set tapping.max_taps=3" in head
        assert "from the first touch" in head
    best = answer_path(run, "best").read_text()
    assert "# skin: platsil_gel_10_marechal (catalogue)" in best
    assert "# core: gel family (mu0_MPa 0.0105, alpha 3.8, g_total 0.555, tau_s 0.0408)" in best
    # the same answers again: every file left as it is
    before = {p: p.stat().st_mtime_ns for p in paths}
    assert write_answer_files(run) == paths
    assert {p: p.stat().st_mtime_ns for p in paths} == before


def test_an_unfinished_run_has_no_answer_files(tmp_path: Path) -> None:
    assert write_answer_files(tmp_path) == [] and not (tmp_path / "answers").exists()


def test_the_families_the_search_used_name_the_materials(run: Path) -> None:
    summary = json.loads((run / "summary.json").read_text())
    skin, core = layer_materials(summary["answers"]["foam"])
    assert (skin.role, skin.family, core.role, core.family) == ("skin", "gel", "core", "foam")
    assert dict(core.parameters)["nu"] == pytest.approx(0.24)
    skin, core = layer_materials(summary["answers"]["buildable"])
    assert (skin.name, core.name, core.family) == (
        "polyurethane_74_45",
        "ecoflex_0010_dawood",
        None,
    )


def test_simulate_runs_a_written_answer_file_and_the_same_answer_by_name(run: Path, capsys):
    write_answer_files(run)
    assert main(["simulate", str(answer_path(run, "best")), "--protocol", "plate"]) == 0
    by_file = capsys.readouterr().out
    assert by_file.startswith("plate_force_at_1mm_N")
    for source in (run, run / "summary.json"):
        assert main(["simulate", str(source), "--answer", "best", "--protocol", "plate"]) == 0
        by_name = capsys.readouterr().out
        assert by_name.splitlines()[:2] == by_file.splitlines()[:2]  # metric and validity


@pytest.mark.parametrize(
    ("name", "words"),
    [
        ("nope", ("--answer", "'nope'", "allowed: best, gel, foam, buildable")),
        ("gel", ("--answer", "no 'gel' answer", "allowed here: best, foam, buildable")),
    ],
)
def test_an_answer_the_run_does_not_have_is_one_line(run: Path, capsys, name, words) -> None:
    assert main(["simulate", str(run), "--answer", name, "--protocol", "plate"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    _one_error_line(err, *words)


def test_a_run_folder_without_answer_says_how_to_name_one(run: Path, capsys) -> None:
    for source in (run, run / "summary.json"):
        assert main(["simulate", str(source), "--protocol", "plate"]) == 2
        _one_error_line(capsys.readouterr().err, "DESIGN", "--answer NAME", "answers/best.toml")
    design = run / "d.toml"
    design.write_text(design_to_toml(DESIGNS["foam core"]))
    assert main(["simulate", str(design), "--answer", "best"]) == 2
    _one_error_line(capsys.readouterr().err, "--answer", "summary.json")


def test_predict_takes_a_written_answer_and_the_same_answer_by_name(run: Path, capsys) -> None:
    write_answer_files(run)
    ckpt = Path(__file__).resolve().parents[1] / "surrogate" / "pretrained" / "default"
    assert main(["predict", str(ckpt), str(answer_path(run, "foam")), "--json"]) == 0
    by_file = json.loads(capsys.readouterr().out)["designs"]
    assert main(["predict", str(ckpt), str(run), "--answer", "foam", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["designs"] == by_file
    assert by_file[0]["in_domain"]
    assert main(["predict", str(ckpt), str(run), "--answer", "worst"]) == 2
    _one_error_line(capsys.readouterr().err, "--answer", "'worst'", "allowed")


def test_report_writes_the_answer_files_of_an_existing_run(run: Path, capsys, monkeypatch):
    monkeypatch.setattr(explore._report, "write_figures", lambda run_dir, workers=1: {})
    assert main(["report", str(run)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1] == f"report: {run / 'report.md'}"
    assert out[0].startswith("answers: ") and str(answer_path(run, "best")) in out[0]
    assert sorted(p.name for p in (run / "answers").iterdir()) == [
        "best.toml",
        "buildable.toml",
        "foam.toml",
    ]


def test_the_cli_names_the_answers_the_summary_has() -> None:
    assert tuple(ANSWER_KINDS) == ANSWER_NAMES


# ---------------------------------------------------------------------------- the report
def test_the_report_leads_with_the_verdict(run: Path, monkeypatch) -> None:
    monkeypatch.setattr(explore._report, "write_figures", lambda run_dir, workers=1: {})
    text = explore._report.write_report(run).read_text()
    title, first = text.split("\n\n")[:2]
    assert title == "# Fingertip skin search: `main`"
    assert first.startswith("**Verdict**: no design of this run meets the targets within ±5 %")
    # the closest credible design, its materials by catalogue name and family
    assert "[`answers/best.toml`](answers/best.toml)" in first
    assert "`platsil_gel_10_marechal` (catalogue)" in first
    assert "a core of the `gel` family (mu0_MPa 0.0105, alpha 3.8" in first
    # its error on each target, in the targets' reading, and what limits it
    assert "read from the first touch" in first
    for err, fe in (("-33.9 %", "1.21 vs 1.83 mm"), ("-28.2 %", "2.09 vs 2.91 mm"),
                    ("-41.2 %", "1.33 vs 2.26 N mm")):  # fmt: skip
        assert f"{err} on the" in first and fe in first
    assert "stiffer than the finger" in first
    assert "log strain of 0.598 against the validity limit of 0.60" in first
    assert "0.167 mm against the 0.37 mm limit" in first
    assert "Of the 5 FE-confirmed designs, 1 went beyond the strain limit, 1 failed." in first
    # and the best buildable one
    assert "The best buildable design" in first and "`ecoflex_0010_dawood` (catalogue)" in first
    # no "custom" material anywhere: every material by its catalogue name or family
    assert "custom" not in text
    # the confirmations: the targets' reading, and why a design has no FE score
    table = text.split("## Confirmed designs: surrogate vs FE")[1].split("\n## ")[0]
    assert "`disp_at_1N_from_touch_mm` error" in table and "`disp_at_1N_mm` error" not in table
    assert "| – (invalid: compressive log strain 0.61 > 0.60 (tapping); stopped there: " in table
    assert "| – (FE failed: tapping: Newton stalled) |" in table
    rows = [r for r in table.splitlines() if r.startswith("| ") and "| – " in r]
    assert len(rows) == 2 and all("| – (" in r for r in rows)


def test_a_run_without_a_credible_design_says_so_first(run: Path, monkeypatch) -> None:
    monkeypatch.setattr(explore._report, "write_figures", lambda run_dir, workers=1: {})
    summary = json.loads((run / "summary.json").read_text())
    summary["answers"] = dict.fromkeys(summary["answers"])
    summary["notes"] = ["no credible answer: of 2 FE-confirmed designs, 2 went beyond the limits"]
    (run / "summary.json").write_text(json.dumps(summary))
    first = explore._report.write_report(run).read_text().split("\n\n")[1]
    assert first == (
        "**Verdict: no credible design.** No credible answer: of 2 FE-confirmed designs, 2 went "
        "beyond the limits."
    )


# ---------------------------------------------------------------------------- --version, --help
def test_version_prints_the_package_version(capsys) -> None:
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"fingertip {metadata.version('fingertip')}"


#: what each subcommand's --help must name: every kind of input it takes
INPUTS = {
    "simulate": ("design TOML", "run folder", "summary.json", "--answer", "catalogue"),
    "predict": (
        "checkpoint",
        "design TOML",
        "design-point TOML",
        "CSV",
        "dataset",
        "run folder",
        "summary.json",
        "--answer",
    ),
    "report": ("run folder", "answers/"),
    "sweep": ("design-space TOML", "catalogue", "sweep folder"),
    "train": ("sweep folder", "dataset"),
    "optimize": (
        "checkpoint",
        "design-space TOML",
        "targets TOML",
        "dataset",
        "catalogue",
        "run folder",
        "answers/",
    ),
    "run": (
        "checkpoint",
        "design-space TOML",
        "targets TOML",
        "dataset",
        "catalogue",
        "run folder",
        "answers/",
    ),
    "fit-material": ("CSV", "catalogue"),
}


@pytest.mark.parametrize("command", sorted(INPUTS))
def test_every_help_names_every_kind_of_input(command: str) -> None:
    parser = build_parser(command)
    sub = next(a for a in parser._actions if a.dest == "command").choices[command]
    text = " ".join(sub.format_help().split())
    missing = [w for w in INPUTS[command] if w not in text]
    assert not missing, f"fingertip {command} --help does not name {missing}"


def test_the_answers_of_the_space_are_the_run_s(run: Path) -> None:
    """The written files are designs of the space the search used: the shipped one here."""
    write_answer_files(run)
    from sim.design import point_from_design

    space = load_space()
    for kind, point in (("best", BEST), ("foam", FOAM), ("buildable", BUILDABLE)):
        design = load_design(answer_path(run, kind), space.catalogue)
        got = point_from_design(design, space)
        assert {k: got[k] for k in point} == pytest.approx(point), kind


def test_the_report_names_the_layer_and_the_limit_that_binds(run: Path, monkeypatch) -> None:
    """An answer whose FE record has each layer's strain and tested limit: the verdict and the
    answer's section name the layer nearest its own limit (the gel core, argued), not the
    design's largest strain against one limit; an override is said to be one."""
    from sim.protocols.validity import LAYER_LIMIT_KEYS, layer_limit

    monkeypatch.setattr(explore._report, "write_figures", lambda run_dir, workers=1: {})
    limits = [layer_limit(m) for m in point_to_design(BEST, CATALOGUE).materials]
    assert [(t.material, t.basis) for t in limits] == [
        ("platsil_gel_10_marechal", "argued"),
        ("family.gel", "argued"),
    ]
    summary = json.loads((run / "summary.json").read_text())
    diagnostics = summary["answers"]["best"]["diagnostics"]
    # the skin strains most (0.56) but the core (0.512) is nearer its own limit (0.528)
    diagnostics.update(
        dict(zip(LAYER_LIMIT_KEYS, ([t.log_strain for t in limits],
             [t.material for t in limits], [t.basis for t in limits]), strict=True)),
        tapping_max_compressive_log_strain=0.56,
        tapping_max_compressive_log_strain_by_layer=[0.56, 0.512],
    )  # fmt: skip
    (run / "summary.json").write_text(json.dumps(summary))
    text = explore._report.write_report(run).read_text()
    first = text.split("\n\n")[1]
    assert (
        "its tapping compresses layer 1 (core, family.gel) to a log strain of 0.512 against its "
        "limit of 0.53 (argued for its material: no test compressed it that far)" in first
    )
    assert "; layer 1 (core, family.gel) at 0.512 against its limit of 0.53 (argued" in text
    # the run's options override every layer's limit: the skin's 0.56 binds, said so
    config = json.loads((run / "config.json").read_text())
    config["sim_options"]["validity"] = {"max_compressive_log_strain": 0.58}
    (run / "config.json").write_text(json.dumps(config))
    first = explore._report.write_report(run).read_text().split("\n\n")[1]
    assert (
        "its tapping compresses layer 0 (skin, platsil_gel_10_marechal) to a log strain of "
        "0.560 against its limit of 0.58 (one limit for every layer: the training sweep's "
        "options or --set validity.max_compressive_log_strain)" in first
    )
