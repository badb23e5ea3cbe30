"""simgap: why your simulation disagrees with your robot.

Rigid-body dynamics of serial arms loaded from URDF (H, C in two formulations, g), closed-loop
simulation and sim-to-real gap diagnosis, implemented in Rust.

Equation of motion, SI units: ``H(q) q̈ + C(q, q̇) q̇ + g(q) = τ`` with ``g = ∂U/∂q`` on the
left-hand side. Every :class:`Model` method takes one state, shape ``(dof,)``, or a batch,
shape ``(N, dof)``, of anything array-like, and returns C-ordered float64 numpy arrays (row
``i`` of a matrix is equation ``i``). Batches release the GIL, run on all cores, and stop with
``KeyboardInterrupt`` on Ctrl-C.
"""

from simgap._simgap import (
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
    diagnose,
    l2,
    l2_tracking,
    read_log,
    simulate,
    write_log,
)

__all__ = [
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
    "l2",
    "l2_tracking",
    "read_log",
    "simulate",
    "write_log",
]
