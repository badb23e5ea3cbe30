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
    directional_friction: bool = False,
    load_stribeck_friction: bool = False,
    link_side_torque: bool = False,
) -> _simgap.Report:
    """Diagnoses the gap between ``model`` and logged runs (the ``simgap diagnose`` pipeline):
    **where** the gap lies, **which** unmodelled effect causes it, and **how far** it shrinks on
    held-out runs once that effect is added.

    ``fit``: runs used to fit and select effects; ``holdout``: runs used only to measure the gap
    before and after (never for fitting). Each is a sequence of :class:`Run` or paths to logs,
    or a single one. ``formulation``: the C of the model under test ("euler_lagrange" or
    "simplified").

    ``experiment``: the experiment (controller, gains, sample period) of runs that carry none,
    e.g. a recorded bag: a ``simgap.experiment`` metadata dict (as ``Run.experiment`` gives it)
    or the path of an experiment JSON file. Runs with their own experiment keep it.

    ``progress``: ``True`` shows a bar naming the current stage (tqdm when installed, else one
    line on stderr); a callable is called as ``progress(stage, done, total)`` on the calling
    thread whenever the diagnosis moves on; ``None`` or ``False`` shows nothing.

    ``urdf``: the URDF file ``model`` was loaded from, kept for :meth:`Report.export_urdf`.

    ``directional_friction``: also try friction that differs with the direction of motion
    (levels and slopes per direction) in place of each joint's Coulomb and viscous friction,
    for ball screws and worn gearboxes (the CLI's ``--directional-friction``; off by default).

    ``load_stribeck_friction``: on servo logs, also try the servo's load friction rising at rest
    (a breakaway level ``fs + mus·|τ_drive|`` above the moving ``fc + mu·|τ_drive|``), for a
    servo that stops short of its goal and stays there while its duty rises (the CLI's
    ``--load-stribeck-friction``; off by default).

    ``link_side_torque``: the logged effort is measured on the link side of the gearbox
    (joint-torque sensors, as on torque-sensing arms), so no rotor inertia or back-EMF is tried:
    both act before such a sensor (the CLI's ``--link-side-torque``; off by default).

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
        return _simgap.diagnose(model, fit, holdout, formulation=formulation, experiment=experiment, progress=callback, urdf=urdf, directional_friction=directional_friction, load_stribeck_friction=load_stribeck_friction, link_side_torque=link_side_torque)  # type: ignore[arg-type]
    finally:
        if close is not None:
            close()
