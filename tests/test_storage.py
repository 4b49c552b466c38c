"""The search's Optuna storage (``explore._storage``): a journal file by default, a database
URL when given, and the repair of what a kill leaves in a journal."""

from __future__ import annotations

import optuna
import pytest

from explore._storage import (
    check_storage,
    dashboard_command,
    default_storage,
    is_database_url,
    open_storage,
    repair_journal,
)
from sim.errors import DesignError


def _trials(n: int) -> list:
    dist = {"x": optuna.distributions.FloatDistribution(0.0, 1.0)}
    return [
        optuna.trial.create_trial(
            params={"x": i / n},
            distributions=dist,
            value=0.1 * i + 1e-17,
            user_attrs={"source": "screen"},
        )
        for i in range(n)
    ]


def test_storage_names():
    assert is_database_url("sqlite:///a/b.db") and is_database_url("postgresql+psycopg://u@h/d")
    assert not is_database_url("runs/x/study.log") and not is_database_url("/abs/study.log")
    assert dashboard_command("runs/x/study.log") == "optuna-dashboard runs/x/study.log"


def test_a_journal_keeps_trials_bit_for_bit(tmp_path):
    spec = default_storage(tmp_path)
    assert spec.endswith("study.log")
    check_storage(spec)  # a new file in an existing folder
    study = optuna.create_study(storage=open_storage(spec), study_name="s")
    study.add_trials(_trials(20))
    again = optuna.load_study(study_name="s", storage=open_storage(spec)).trials
    assert [(t.params, t.values, t.user_attrs) for t in again] == [
        (t.params, t.values, t.user_attrs) for t in _trials(20)
    ]


def test_repair_drops_a_cut_line_and_a_stale_lock_so_the_journal_takes_more(tmp_path):
    spec = default_storage(tmp_path)
    study = optuna.create_study(storage=open_storage(spec), study_name="s")
    study.add_trials(_trials(5))
    whole = (tmp_path / "study.log").read_bytes()
    study.add_trials(_trials(1))
    cut = (tmp_path / "study.log").read_bytes()[: len(whole) + 25]  # a kill mid-append
    (tmp_path / "study.log").write_bytes(cut)
    (tmp_path / "study.log.lock").write_text("")  # the killed writer held the lock
    (tmp_path / "study.log.lock0a1b.rename").write_text("")  # or was releasing one
    assert repair_journal(tmp_path / "study.log") == (
        "removed a stale lock; removed a released lock's leftover; dropped a cut last line"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["study.log"]
    assert (tmp_path / "study.log").read_bytes() == whole
    assert repair_journal(tmp_path / "study.log") is None  # nothing left to do
    study = optuna.load_study(study_name="s", storage=open_storage(spec))
    study.add_trials(_trials(3))
    assert len(optuna.load_study(study_name="s", storage=open_storage(spec)).trials) == 8


def test_a_journal_in_a_missing_folder_or_a_folder_is_refused(tmp_path):
    with pytest.raises(DesignError, match="no folder"):
        check_storage(str(tmp_path / "missing" / "study.log"))
    (tmp_path / "dir.log").mkdir()
    with pytest.raises(DesignError, match="is a folder"):
        check_storage(str(tmp_path / "dir.log"))
    (tmp_path / "text.log").write_text("hello\n")
    with pytest.raises(DesignError, match="not an Optuna journal"):
        check_storage(str(tmp_path / "text.log"))
