"""simgap: why your simulation disagrees with your robot.

Rigid-body dynamics of serial arms loaded from URDF (H, C in two formulations, g), closed-loop
simulation and sim-to-real gap diagnosis, implemented in Rust.

Equation of motion, SI units: ``H(q) q̈ + C(q, q̇) q̇ + g(q) = τ`` with ``g = ∂U/∂q`` on the
left-hand side. Every :class:`Model` method takes one state, shape ``(dof,)``, or a batch,
shape ``(N, dof)``, of anything array-like, and returns C-ordered float64 numpy arrays (row
``i`` of a matrix is equation ``i``). Batches release the GIL, run on all cores, and stop with
``KeyboardInterrupt`` on Ctrl-C.

:func:`diagnose` returns a :class:`Report` that notebooks show as the HTML report; the optional
:mod:`simgap.plot` module (``pip install "simgap[plot]"``, matplotlib) draws its figures.
"""

from simgap._simgap import (
    DIAGNOSE_SWITCHES,
    DimensionError,
    DynamicsError,
    FitError,
    L2Report,
    LogError,
    Model,
    Report,
    Run,
    SimgapError,
    SimulationError,
    UrdfError,
    __version__,
    compare,
    effect_vocabulary,
    l2,
    l2_tracking,
    lerobot_episodes,
    read_log,
    read_logs,
    simulate,
    write_log,
)
from simgap._diagnose import diagnose

__all__ = [
    "DIAGNOSE_SWITCHES",
    "DimensionError",
    "DynamicsError",
    "FitError",
    "L2Report",
    "LogError",
    "Model",
    "Report",
    "Run",
    "SimgapError",
    "SimulationError",
    "UrdfError",
    "__version__",
    "compare",
    "diagnose",
    "effect_vocabulary",
    "l2",
    "l2_tracking",
    "lerobot_episodes",
    "read_log",
    "read_logs",
    "simulate",
    "write_log",
]
