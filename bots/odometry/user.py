"""A user's own odometry estimator beside the shipped ones: loaded from a file, named, and
checked every step as a controller's command is.

An estimator follows `bots.odometry.base.Estimator`: `reset(robot, pose)`, `update(readings)`, a `pose`
(3,) and optionally a `covariance` (3, 3). `ctsim run --estimator FILE.py:Class` and
`simulate(..., estimators=[...])` give every robot a fresh one beside its defaults, which stay in
their compiled pass (`beside_defaults`; `--estimator localiser`: the shipped Monte Carlo localiser,
`bots.odometry.localiser`); its name is its `name` attribute (else the class's), which must be a
plain word (it names files) and differ from the others'. A step whose update raises, or leaves a
pose or covariance of the wrong shape or not finite, ends the run as a controller's error does
(`check`). An estimator with a `use_map(scan, rng)` method is handed, before `reset`, the robot's
map of the world (a `bots.odometry.particles.MapModel`: the likelihood of an IR scan at any pose,
never the true pose) and a generator spawned from the run's seed.
"""

from __future__ import annotations

import copy
import inspect
import math
import re
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from bots.controller import did, user_module, where
from bots.odometry.base import Estimator
from bots.odometry.defaults import default_estimators
from bots.odometry.localiser import MonteCarloLocaliser
from bots.spec import RobotSpec
from sim.errors import UserCodeFailed, UserError
from sim.interrupts import Counting

NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,39}")
"""What an estimator's name may be: it is part of file names (`<name>.tum`) and column names."""


class EstimatorError(UserError):
    """A user estimator that cannot be loaded or named (message for the CLI)."""


SHIPPED: dict[str, Callable[[], Estimator]] = {"localiser": MonteCarloLocaliser}
"""Estimators ctsim ships beside the defaults, by the name `--estimator` takes (a file of that
name, if there is one, comes first)."""


def load(source: str) -> Callable[[], Estimator]:
    """The estimator class (or factory) of `FILE.py[:NAME]`: the one named, else the file's only
    class with `reset` and `update` methods; or a shipped one by name (`SHIPPED`)."""
    if source in SHIPPED and not Path(source).is_file():
        return SHIPPED[source]
    file, _, name = source.partition(":") if not Path(source).is_file() else (source, "", "")
    path = Path(file)
    module = user_module(path, "estimator", EstimatorError)
    if name:
        if not hasattr(module, name):
            raise EstimatorError(f"{path}: defines no {name!r}")
        return getattr(module, name)
    found = [v for v in vars(module).values() if inspect.isclass(v) and v.__module__ == module.__name__ and hasattr(v, "update") and hasattr(v, "reset")]
    if len(found) != 1:
        raise EstimatorError(f"{path}: expected one class with reset(robot, pose) and update(readings) methods, found {len(found)}; name it with FILE.py:CLASS")
    return found[0]


def made(given: Any) -> Estimator:
    """A fresh estimator from a class, a factory, an estimator object (copied) or `FILE.py:NAME`."""
    if isinstance(given, str | Path):
        given = load(str(given))
    label = getattr(given, "__name__", given)
    if hasattr(given, "update") and not inspect.isclass(given):
        try:
            return copy.deepcopy(given)
        except Exception as err:  # (a lock, a generator or an open file in it: copying it can raise anything)
            raise EstimatorError(f"estimator {name_of(given)!r} cannot be copied for each robot ({type(err).__name__}: {err}); give its class instead") from None
    counted = Counting()  # (a KeyboardInterrupt the code raises is its error; Ctrl-C stops)
    try:
        with counted:
            estimator = given()
    except (TypeError, ValueError) as err:  # a constructor that wants what it is not given
        raise EstimatorError(f"estimator {label!r} could not be made: {type(err).__name__}: {err}") from None
    except (Exception, SystemExit, KeyboardInterrupt) as err:  # the user's code failing (or leaving): theirs, not a way out of ctsim
        if counted.by_signal(err):
            raise
        raise UserCodeFailed(f"estimator {label!r}: making it {did(err)}{where(err)}") from None
    if not (hasattr(estimator, "reset") and hasattr(estimator, "update")):
        raise EstimatorError(f"{label!r} is not an estimator: it needs reset(robot, pose) and update(readings) methods")
    return estimator


def name_of(estimator: Estimator) -> str:
    """An estimator's label: its `name`, else (none, or one that cannot be read) its class's name."""
    try:
        return str(getattr(estimator, "name", None) or type(estimator).__name__)
    except Exception:  # (a `name` property that raises, a name whose str raises)
        return type(estimator).__name__


def beside_defaults(robot: RobotSpec, extra: Iterable[Any]) -> list[Estimator]:
    """A fresh one of each `extra`, to run beside the robot's default estimators (which stay in
    their compiled pass), each named apart from those and from the others."""
    chosen = [made(given) for given in extra]
    seen = {name_of(estimator) for estimator in default_estimators(robot)}
    for estimator in chosen:
        label = name_of(estimator)
        if not NAME.fullmatch(label):
            raise EstimatorError(f"estimator name {label!r}: use letters, digits, '_', '.' or '-' (at most 40; it names files)")
        if label in seen or label == "truth":
            raise EstimatorError(f"estimator name {label!r} is taken; give yours another `name`")
        seen.add(label)
        try:
            if getattr(estimator, "name", None) != label:
                estimator.name = label
        except Exception:  # (a read-only `name`, or one that raises: its label stays the one above)
            pass
    return chosen


ROUND_OFF = 1e-9
"""Relative asymmetry or negative eigenvalue (of the covariance's largest entry) a covariance may
have from floating-point rounding: products of doubles differ in the 16th digit, a propagated
covariance after hours of steps in the 10th at most."""


def outputs(estimator: Estimator, uncertain: bool) -> tuple[np.ndarray | tuple[float, float, float] | None, np.ndarray | None, str | None]:
    """An estimator's pose and covariance (None where it has none) after an update, each read once
    and copied, so that what is checked is what is logged (a property that answers differently
    when read again, or an array another estimator changes later, cannot slip past the check; a
    pose of three floats is kept as a tuple of them, which nothing can change, else an array);
    and what is wrong with them (None: nothing): a pose that is not 3 finite numbers, a
    covariance that is not a finite, symmetric, positive semi-definite (3, 3) matrix (a
    covariance that is none would make its NEES nonsense). `uncertain`: whether it reports a
    covariance (`has_covariance`, asked once when the run starts: its logged columns)."""
    pose, problem = _numbers(getattr(estimator, "pose", None), (3,), "pose")
    covariance = None
    if problem is None and uncertain:
        covariance, problem = _numbers(estimator.covariance, (3, 3), "covariance")
        problem = problem or _covariance(covariance)
    return pose, covariance, problem


def has_covariance(estimator: Estimator) -> bool:
    """Whether an estimator reports a covariance (the Protocol's optional `covariance`; one whose
    asking raises is taken to have one, and fails where it is read, in the guarded update)."""
    try:
        return hasattr(type(estimator), "covariance") or hasattr(estimator, "covariance")
    except Exception:  # (a __getattr__ that raises something else than AttributeError)
        return True


def _covariance(cov: np.ndarray) -> str | None:
    scale = ROUND_OFF * max(float(np.abs(cov).max()), np.finfo(float).tiny)
    i, j = np.unravel_index(np.argmax(np.abs(cov - cov.T)), cov.shape)
    if abs(cov[i, j] - cov[j, i]) > scale:
        return f"its covariance is not symmetric ([{i}, {j}] = {cov[i, j]:.6g}, [{j}, {i}] = {cov[j, i]:.6g})"
    lowest = float(np.linalg.eigvalsh(cov).min())
    if lowest < -scale:
        return f"its covariance is not positive semi-definite (an eigenvalue of {lowest:.6g})"
    return None


_SEQUENCES = (list, tuple)
_FLOATS = (float, np.float64)
"""A pose's containers and numbers that `_numbers` takes the short way (others: numpy's)."""


def _numbers(value: Any, shape: tuple[int, ...], what: str) -> tuple[np.ndarray | tuple[float, float, float] | None, str | None]:
    """`value` as a fresh array of `shape` (a pose of three floats: a tuple of them, immutable as
    an array's copy, without numpy's calls), or None and what is wrong with it."""
    if type(value) in _SEQUENCES and len(value) == 3 and shape == (3,):
        x, y, heading = value
        # (finite, every one, where their sum is; a sum that overflows goes the long way below)
        if type(x) in _FLOATS and type(y) in _FLOATS and type(heading) in _FLOATS and math.isfinite(x + y + heading):
            return (x, y, heading), None
    if type(value) is np.ndarray and value.shape == shape and value.dtype == np.float64:
        array = value.copy()
        if math.isfinite(array.sum()):  # every entry finite, told in a microsecond (a sum that overflows goes the long way below)
            return array, None
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        return None, f"its {what} is not numbers ({type(value).__name__})"
    if array.shape != shape:
        return None, f"its {what} has shape {array.shape}; expected {shape}"
    if not np.isfinite(array).all():
        bad = next(float(v) for v in array.ravel() if not math.isfinite(v))
        return None, f"its {what} is not finite ({bad})"
    return array, None
