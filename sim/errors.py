"""Errors raised for invalid user input and for failed simulations."""

from __future__ import annotations


class DesignError(ValueError):
    """Invalid design or material input.

    ``field`` is the dotted path of the offending key (``layers[1].material.nu``) so the CLI can
    print one line naming it; ``message`` says what is allowed.
    """

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message

    def __reduce__(self) -> tuple[type[DesignError], tuple[str, str]]:
        """Pickled as (field, message): raised in a worker process, it reaches the parent
        whole (the default pickles the one joined text, which ``__init__`` cannot take)."""
        return type(self), (self.field, self.message)


class SimulationError(RuntimeError):
    """A protocol that did not converge even after step cutting.

    ``protocol`` names the loading protocol and ``time_s`` the simulated time at which the solver
    gave up.
    """

    def __init__(self, protocol: str, time_s: float, reason: str) -> None:
        super().__init__(f"{protocol}: failed at t = {time_s:.4g} s: {reason}")
        self.protocol = protocol
        self.time_s = time_s
        self.reason = reason


#: The largest seed of every command (``--seed``): seeds are integers in [0, 2**32 - 1]. The
#: narrowest of the generators they seed decides: Optuna's TPE and NSGA-II samplers seed numpy's
#: ``RandomState`` (Mersenne Twister), which takes [0, 2**32 - 1] and raises beyond ("Seed must
#: be between 0 and 2**32 - 1"); ``numpy.random.SeedSequence`` (the training's split, weights
#: and minibatches), scipy's Sobol / Latin-hypercube samplers and ``torch.Generator`` take any
#: non-negative integer, none a negative one. One range for every command, so that a seed one
#: command takes the others take too; 4 294 967 296 seeds are more than any study needs.
SEED_MAX = 2**32 - 1


def check_seed(seed: object, field: str = "--seed", uses: int = 1) -> int:
    """``seed`` if it is an integer and the ``uses`` seeds ``seed``, ..., ``seed + uses - 1``
    (a search's round r seeds its samplers with ``seed + r``) lie in [0, ``SEED_MAX``]; else a
    ``DesignError`` naming ``field`` and the allowed range."""
    high = SEED_MAX - (uses - 1)
    why = "" if uses == 1 else f" (round r seeds its search with seed + r, {uses} rounds)"
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= high:
        raise DesignError(field, f"must be an integer in [0, {high}]{why}, got {seed!r}")
    return seed


def read_bytes(path, field: str, kind: str) -> bytes:
    """The bytes of a file; missing, a directory or unreadable is one ``DesignError`` naming
    ``field`` (``kind``: what the file should be, e.g. "TOML file", "CSV file")."""
    from pathlib import Path

    path = Path(path)
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise DesignError(field, f"no such file: {path}") from None
    except IsADirectoryError:
        raise DesignError(field, f"{path} is a directory, not a {kind}") from None
    except OSError as exc:
        raise DesignError(field, f"cannot read {path}: {exc.strerror}") from None


def read_toml(path, field: str) -> dict:
    """Parse a TOML file; any failure (missing, a directory, unreadable, not UTF-8, malformed)
    becomes one ``DesignError`` naming ``field`` (e.g. "DESIGN", "SPACE", "TARGETS")."""
    import tomllib

    raw = read_bytes(path, field, "TOML file")
    try:
        return tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise DesignError(field, f"{path} is not UTF-8 text (TOML files must be)") from None
    except tomllib.TOMLDecodeError as exc:
        raise DesignError(field, f"malformed TOML in {path}: {exc}") from None
