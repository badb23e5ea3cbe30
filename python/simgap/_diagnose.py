"""``simgap.diagnose``: the bound diagnosis with a progress bar for notebooks and terminals."""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping, Sequence
from os import PathLike
from typing import Any

from simgap import _simgap

ProgressCallback = Callable[[str, int, int], object]


def _text_progress() -> tuple[ProgressCallback, Callable[[], None]]:
    """A one-line progress display on stderr, for when tqdm is not installed."""

    def show(stage: str, done: int, total: int) -> None:
        print(f"\r{stage}: {done}/{total}   ", end="", file=sys.stderr, flush=True)

    def close() -> None:
        print(file=sys.stderr)

    return show, close


def _tqdm_progress() -> tuple[ProgressCallback, Callable[[], None]]:
    """A tqdm bar (notebook-aware through ``tqdm.auto``) that names the current stage."""
    try:
        from tqdm.auto import tqdm  # type: ignore[import-untyped]
    except ImportError:
        return _text_progress()
    bar = tqdm(total=1, unit="step", dynamic_ncols=True)
    current = {"stage": ""}

    def show(stage: str, done: int, total: int) -> None:
        if stage != current["stage"]:
            current["stage"] = stage
            bar.reset(total=max(total, 1))
            bar.set_description(stage)
        bar.total = max(total, 1)
        bar.n = done
        bar.refresh()

    return show, bar.close


def diagnose(
    model: _simgap.Model,
    fit: Sequence[Any] | Any,
    holdout: Sequence[Any] | Any = (),
    *,
    formulation: str = "euler_lagrange",
    experiment: Mapping[str, object] | str | PathLike[str] | None = None,
    progress: bool | ProgressCallback | None = None,
    urdf: str | PathLike[str] | None = None,
    calibration: str | PathLike[str] | None = None,
    **switches: bool,
) -> _simgap.Report:
    """Diagnoses the gap between ``model`` and logged runs (the ``simgap diagnose`` pipeline):
    **where** the gap lies, **which** unmodelled effect causes it, and **how far** it shrinks on
    held-out runs once that effect is added.

    ``fit``: runs used to fit and select effects; ``holdout``: runs used only to measure the gap
    before and after (never for fitting). Each is a sequence of :class:`Run` or paths to logs,
    or a single one; a LeRobot dataset path (``FOLDER`` or ``FOLDER#0,3-5``) gives one run per
    episode, named ``FOLDER#N``. ``formulation``: the C of the model under test ("euler_lagrange" or
    "simplified").

    ``experiment``: the experiment (controller, gains, sample period) of runs that carry none,
    e.g. a recorded bag: a ``simgap.experiment`` metadata dict (as ``Run.experiment`` gives it)
    or the path of an experiment JSON file. Runs with their own experiment keep it.

    ``progress``: ``True`` shows a bar naming the current stage (tqdm when installed, else one
    line on stderr); a callable is called as ``progress(stage, done, total)`` on the calling
    thread whenever the diagnosis moves on; ``None`` or ``False`` shows nothing.

    ``urdf``: the URDF file ``model`` was loaded from, kept for :meth:`Report.export_urdf`.

    ``calibration``: LeRobot's calibration file of the robot, which makes a range-normalised
    joint of a LeRobot dataset (the gripper's 0–100) an angle. Without it such a joint is left
    out of the runs and the model joint of that name is locked at its zero position; the
    report's notes say so.

    ``**switches``: the diagnosis' yes/no options by keyword, the same as ``simgap diagnose``'s
    flags (``directional_friction=True`` is ``--directional-friction``), listed with their
    defaults in :data:`simgap.DIAGNOSE_SWITCHES` and below. A keyword that is no switch, or a
    value that is not a bool, raises TypeError.

    Returns a :class:`Report`, which a notebook displays as the HTML report. Ctrl-C raises
    KeyboardInterrupt; errors as :func:`simgap._simgap.diagnose`.
    """
    close: Callable[[], None] | None = None
    callback: ProgressCallback | None
    if progress is True:
        callback, close = _tqdm_progress()
    elif progress is None or progress is False:
        callback = None
    elif callable(progress):
        callback = progress
    else:
        raise TypeError(f"progress: expected True, False, None or a callable (stage, done, total), got {type(progress).__name__}")
    try:
        return _simgap.diagnose(model, fit, holdout, formulation=formulation, experiment=experiment, progress=callback, urdf=urdf, calibration=calibration, **switches)  # type: ignore[arg-type]
    finally:
        if close is not None:
            close()


# the switches, listed from the one table the CLI's flags are built from
diagnose.__doc__ = (diagnose.__doc__ or "") + "".join(
    f"\n    ``{name}`` (default {default}): {help}\n" for name, default, help in _simgap.DIAGNOSE_SWITCHES
)
