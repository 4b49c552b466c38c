"""Several ``fingertip optimize`` workers on one study through a real PostgreSQL server: the
trials add up (none lost, none duplicated, the seeds added once), and a worker killed with
kill -9 resumes its study to the end.

The server is a throwaway one made here with the system's ``initdb`` and ``pg_ctl`` (in a
temporary folder, reached by its Unix socket only, no TCP port). PostgreSQL refuses to run as
root, so as root it runs as the unprivileged ``postgres`` (or ``nobody``) user through
``runuser``. Without the server binaries, the driver (``pip install .[postgres]``) or a way to
run them, the tests are skipped, saying why."""

from __future__ import annotations

import os
import pwd
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import optuna
import pytest
from sweep_fixtures import TINY, tiny_surrogate

import explore.cli

pytestmark = pytest.mark.slow

REPO = Path(explore.cli.__file__).resolve().parents[1]
#: the seeds of every study (``SearchSettings.screen_keep``)
SEEDS = 64
BATCH = 16


def _bindir() -> Path | None:
    """The folder of ``initdb`` and ``pg_ctl``: on the PATH, else Debian's versioned one."""
    found = shutil.which("initdb")
    if found:
        return Path(found).resolve().parent
    versions = sorted(Path("/usr/lib/postgresql").glob("*/bin/initdb"),
                      key=lambda p: int(p.parts[-3]) if p.parts[-3].isdigit() else 0)  # fmt: skip
    return versions[-1].parent if versions else None


def _unprivileged() -> tuple[list[str], str | None]:
    """How to run the server's commands (a prefix) and the user who owns its files (None: the
    current one); PostgreSQL refuses root."""
    if os.geteuid() != 0:
        return [], None
    if shutil.which("runuser") is None:
        pytest.skip("running as root without runuser: no way to start PostgreSQL unprivileged")
    for user in ("postgres", "nobody"):
        try:
            pwd.getpwnam(user)
        except KeyError:
            continue
        return ["runuser", "-u", user, "--"], user
    pytest.skip("running as root and no unprivileged user (postgres, nobody) to run PostgreSQL")


@dataclass(frozen=True)
class Server:
    socket_dir: Path

    def connect(self, dbname: str = "postgres"):
        import psycopg

        return psycopg.connect(host=str(self.socket_dir), user="postgres", dbname=dbname,
                               autocommit=True)  # fmt: skip

    def database(self, name: str) -> str:
        """A new empty database; returns its SQLAlchemy URL (the psycopg 3 driver)."""
        with self.connect() as con:
            con.execute(f'CREATE DATABASE "{name}"')
        return f"postgresql+psycopg://postgres@/{name}?host={self.socket_dir}"


@pytest.fixture(scope="module")
def postgres() -> Server:
    """A throwaway PostgreSQL server for the module (trust authentication, socket only)."""
    pytest.importorskip("psycopg", reason="the PostgreSQL driver: pip install .[postgres]")
    bindir = _bindir()
    if bindir is None or not (bindir / "pg_ctl").exists():
        pytest.skip("no PostgreSQL server binaries (initdb, pg_ctl) on this machine")
    prefix, user = _unprivileged()
    root = Path(tempfile.mkdtemp(prefix="fingertip-pg-"))  # short: a socket path is <108 bytes
    if user is not None:
        shutil.chown(root, user)
    data = root / "data"
    ctl = [*prefix, str(bindir / "pg_ctl"), "-D", str(data)]
    try:
        init = [*prefix, str(bindir / "initdb"), "-D", str(data), "-U", "postgres",
                "--auth=trust", "--no-sync", "-E", "UTF8"]  # fmt: skip
        opts = f"-c listen_addresses='' -k {root} -c fsync=off -c max_connections=50"
        start = [*ctl, "-w", "-t", "60", "-l", str(root / "log"), "-o", opts, "start"]
        for cmd in (init, start):
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
            if proc.returncode != 0:
                why = (proc.stderr or proc.stdout).strip().splitlines() or ["?"]
                pytest.skip(f"cannot start PostgreSQL ({Path(cmd[len(prefix)]).name}: {why[-1]})")
        yield Server(root)
    finally:
        if (data / "postmaster.pid").exists():
            subprocess.run([*ctl, "-m", "immediate", "-w", "stop"], capture_output=True,
                           timeout=60)  # fmt: skip
        shutil.rmtree(root, ignore_errors=True)


def _env() -> dict[str, str]:
    return {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1"}


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> Path:
    """A real FE sweep of the tiny space (10 designs, fast options) and a small surrogate."""
    return tiny_surrogate(tmp_path_factory.mktemp("pg"), TINY)


def _optimize(ckpt: Path, out: Path, url: str, trials: int) -> list[str]:
    return [
        sys.executable, "-m", "explore.cli", "optimize", "--surrogate", str(ckpt),
        "--out", str(out), "--storage", url, "--study", "team", "--trials", str(trials),
        "--screen", "1024", "--rounds", "1", "--confirm", "1", "--uncertain", "0",
        "--buildable-trials", "0", "--family-trials", "0", "--workers", "1", "--no-progress",
    ]  # fmt: skip


def _worker(out: Path) -> str:
    """The name a worker gives its trials (``explore._pipeline.optimize``)."""
    return f"{socket.gethostname()}:{out.resolve()}"


def _start(args: list[str]) -> subprocess.Popen:
    return subprocess.Popen(args, cwd=REPO, env=_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip


def _finish(proc: subprocess.Popen) -> None:
    _, err = proc.communicate(timeout=900)
    assert proc.returncode == 0, err


def _check(trials: list, workers: list[str], n: int) -> Counter:
    """The shared study's invariants; returns the sampled trials of each worker."""
    numbers = [t.number for t in trials]
    assert len(set(numbers)) == len(numbers) == len(trials)
    states = Counter(t.state for t in trials)
    assert set(states) <= {optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.FAIL}
    seeds = [t for t in trials if t.user_attrs.get("source") == "screen"]
    assert len(seeds) == SEEDS  # added once, by one worker
    assert all("worker" not in t.user_attrs for t in seeds)
    others = [t for t in trials if t.user_attrs.get("source") != "screen"]
    by = Counter(t.user_attrs.get("worker") for t in others)
    assert set(by) <= set(workers)  # every other trial is a worker's
    assert len(trials) == SEEDS + sum(by.values())  # they add up
    params = Counter(tuple(sorted(t.params.items())) for t in trials if t.params)
    assert max(params.values()) == 1, "a design stored twice"
    sampled = [t for t in others if not t.user_attrs.get("abandoned")]
    # the workers stop once the study holds n: together at most a batch more per extra worker
    assert n <= len(sampled) < n + BATCH * (len(workers) - 1) + 1
    return by


def test_two_workers_share_one_study(model, postgres, tmp_path):
    """Two `fingertip optimize` processes started together on one PostgreSQL study: both add
    trials, every trial is stored once, the seeds once, and both runs finish."""
    url = postgres.database("together")
    n = 256
    outs = [tmp_path / "a", tmp_path / "b"]
    t0 = time.perf_counter()
    procs = [_start(_optimize(model, out, url, n)) for out in outs]
    for proc in procs:
        _finish(proc)
    wall = time.perf_counter() - t0
    study = optuna.load_study(study_name="team-r0-continuous", storage=url)
    by = _check(study.trials, [_worker(o) for o in outs], n)
    assert all(by[_worker(o)] > 0 for o in outs), f"one worker did all the trials: {by}"
    seeder = study.user_attrs["seeder"]
    assert seeder in {_worker(o) for o in outs} and study.user_attrs["seeds"] == SEEDS
    for out in outs:
        assert (out / "summary.json").exists()
    print(f"{len(study.trials)} trials ({SEEDS} seeds, by worker {sorted(by.values())}), "
          f"{wall:.1f} s")  # fmt: skip


def _finished(postgres: Server, db: str, study: str) -> int:
    """Finished trials of ``study``, read with plain SQL (0 before the tables exist)."""
    import psycopg

    sql = ("SELECT COUNT(*) FROM trials JOIN studies USING (study_id) "
           "WHERE study_name = %s AND state IN ('COMPLETE', 'FAIL')")  # fmt: skip
    try:
        with postgres.connect(db) as con:
            return con.execute(sql, (study,)).fetchone()[0]
    except psycopg.errors.UndefinedTable:
        return 0


def test_a_killed_worker_resumes_its_study(model, postgres, tmp_path):
    """kill -9 a worker mid-search: the trials it left running are failed as abandoned when it
    is run again, and the study ends with exactly the asked trials, keeping every finished one."""
    url = postgres.database("killed")
    name = "team-r0-continuous"
    n = 256
    out = tmp_path / "a"
    args = _optimize(model, out, url, n)
    proc = subprocess.Popen(args, cwd=REPO, env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)  # fmt: skip
    # mid-batch (told one by one): the rest of the batch is left running
    stored, deadline = 0, time.monotonic() + 600
    while (
        time.monotonic() < deadline
        and proc.poll() is None
        and not (stored >= SEEDS + 64 and (stored - SEEDS) % BATCH)
    ):
        time.sleep(0.02)
        stored = _finished(postgres, "killed", name)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    before = optuna.load_study(study_name=name, storage=url).trials
    done = [t for t in before if t.state.is_finished()]
    assert SEEDS + 64 <= len(done) < SEEDS + n, f"not caught mid-search ({len(done)} trials)"
    running = sum(t.state == optuna.trial.TrialState.RUNNING for t in before)
    assert running > 0, "the kill did not land mid-batch"

    _finish(_start(args))
    study = optuna.load_study(study_name=name, storage=url)
    by = _check(study.trials, [_worker(out)], n)
    abandoned = [t for t in study.trials if t.user_attrs.get("abandoned")]
    assert len(abandoned) == running
    assert all(t.state == optuna.trial.TrialState.FAIL for t in abandoned)
    after = {t.number: t for t in study.trials}
    for t in done:  # every trial finished before the kill is kept as it was
        assert after[t.number].params == t.params and after[t.number].values == t.values
    assert (out / "summary.json").exists()
    print(
        f"killed at {len(done)} finished + {running} running trials; resumed to "
        f"{len(study.trials)} ({by[_worker(out)]} by the worker, {len(abandoned)} abandoned)"
    )
