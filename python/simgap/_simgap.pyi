"""The simgap extension module (Rust). Import from :mod:`simgap` instead."""

from os import PathLike
from typing import Literal, TypeAlias, final

import numpy as np
import numpy.typing as npt

__version__: str

_Formulation: TypeAlias = Literal["euler_lagrange", "euler-lagrange", "simplified"]
"""Which Coriolis matrix C: ``"euler_lagrange"`` (Christoffel symbols; Ḣ − 2C skew-symmetric,
C q̇ the true torque) or ``"simplified"`` (C = Ḣ/2, symmetric; C q̇ lacks the skew part)."""

_ArrayLike: TypeAlias = npt.ArrayLike
"""Anything numpy converts to a float64 array: arrays of any dtype and order, lists, tuples."""

_FloatArray: TypeAlias = npt.NDArray[np.float64]
"""A C-ordered float64 numpy array."""

class SimgapError(Exception):
    """Base class of every error raised by simgap."""

class UrdfError(SimgapError):
    """A URDF file that cannot be read or loaded, or an invalid model; the message names the file and the element."""

class LogError(SimgapError):
    """A log (MCAP or CSV) that cannot be read or written, or whose joints do not match the model."""

class DimensionError(SimgapError, ValueError):
    """An array argument of the wrong shape; the message names the argument and says what was expected and what was found."""

class DynamicsError(SimgapError, ValueError):
    """The dynamics are undefined at this input: non-finite values where finite ones are needed, or a mass matrix that is not positive definite."""

class SimulationError(SimgapError):
    """A simulation that diverged, was interrupted, or was given invalid parameters."""

class FitError(SimgapError):
    """An identification or diagnosis that cannot proceed (too little data, a singular problem)."""

@final
class Model:
    """A serial robot model (joint placements, axes, link inertias, gravity), loaded once from URDF.

    Equation of motion, SI units: H(q) q̈ + C(q, q̇) q̇ + g(q) = τ, with g = ∂U/∂q on the left.
    Joint vectors follow ``joint_names``. Every dynamics method accepts one state, shape
    ``(dof,)``, or a batch, shape ``(N, dof)``, of anything array-like, and returns C-ordered
    float64 arrays (row i of a matrix = equation i): matrices ``(dof, dof)`` or
    ``(N, dof, dof)``, vectors ``(dof,)`` or ``(N, dof)``. Batches release the GIL, use all
    cores and can be interrupted with Ctrl-C (``KeyboardInterrupt``).

    Raises DimensionError (a ValueError) when an argument's shape does not match ``dof`` or the
    other arguments, naming the argument: ``"qd: expected 2, got 3 (...)"``.
    """

    @staticmethod
    def from_urdf(path: str | PathLike[str], tip: str | None = None) -> Model:
        """Loads the serial chain of a URDF file, from its root link to ``tip``.

        ``tip`` defaults to the end of the unique chain of movable joints. Fixed joints are
        merged into their parent link; subtrees off the chain (e.g. gripper fingers) are merged
        rigidly at their zero position, with a warning in ``warnings``.

        Raises UrdfError (naming the file and the element) if the file cannot be read or loaded.
        """

    @staticmethod
    def paper_arm() -> Model:
        """The seed paper's planar two-link arm (Table 2): vertical plane, q = 0 hanging down."""

    @property
    def name(self) -> str:
        """Robot name (from the URDF)."""

    @property
    def dof(self) -> int:
        """Number of degrees of freedom (movable joints of the chain)."""

    @property
    def joint_names(self) -> list[str]:
        """Joint names in chain order, root to tip: the order of every joint vector."""

    @property
    def lower_limits(self) -> _FloatArray:
        """Lower position limits [rad or m], shape (dof,); -inf for continuous joints."""

    @property
    def upper_limits(self) -> _FloatArray:
        """Upper position limits [rad or m], shape (dof,); +inf for continuous joints."""

    @property
    def effort_limits(self) -> _FloatArray:
        """Effort limits [N·m or N], shape (dof,)."""

    @property
    def velocity_limits(self) -> _FloatArray:
        """Velocity limits [rad/s or m/s], shape (dof,)."""

    @property
    def gravity(self) -> _FloatArray:
        """Gravity acceleration in the base frame [m/s²], shape (3,); default (0, 0, -9.81).

        Settable with any 3 finite numbers (DimensionError / DynamicsError otherwise); a batch
        already running keeps the gravity it started with.
        """

    @gravity.setter
    def gravity(self, gravity: _ArrayLike) -> None: ...
    @property
    def warnings(self) -> list[str]:
        """Warnings raised while loading (massless links, locked off-chain joints)."""

    def mass_matrix(self, q: _ArrayLike) -> _FloatArray:
        """Mass matrix H(q) (composite rigid body algorithm): symmetric positive definite.

        ``q``: joint positions, shape (dof,) or (N, dof). Returns (dof, dof) or (N, dof, dof).
        """

    def coriolis_matrix(self, q: _ArrayLike, qd: _ArrayLike, formulation: _Formulation = "euler_lagrange") -> _FloatArray:
        """Coriolis matrix C(q, q̇) of the chosen formulation.

        ``q``, ``qd``: positions and velocities, shape (dof,) or (N, dof), the same for both.
        Returns (dof, dof) or (N, dof, dof). Euler–Lagrange: Ḣ − 2C is skew-symmetric;
        simplified: C = Ḣ/2.
        """

    def mass_matrix_derivative(self, q: _ArrayLike, qd: _ArrayLike) -> _FloatArray:
        """Time derivative of the mass matrix, Ḣ(q, q̇) = Σ_k ∂H/∂q_k q̇_k.

        ``q``, ``qd``: shape (dof,) or (N, dof). Returns (dof, dof) or (N, dof, dof).
        """

    def coriolis_torques(self, q: _ArrayLike, qd: _ArrayLike, formulation: _Formulation = "euler_lagrange") -> _FloatArray:
        """Coriolis and centrifugal torques C(q, q̇) q̇ of the chosen formulation.

        ``q``, ``qd``: shape (dof,) or (N, dof). Returns (dof,) or (N, dof).
        """

    def gravity_torques(self, q: _ArrayLike) -> _FloatArray:
        """Gravity torques g(q) = ∂U/∂q; equivalent to ``inverse_dynamics(q, 0, 0)``.

        ``q``: shape (dof,) or (N, dof). Returns (dof,) or (N, dof).
        """

    def inverse_dynamics(self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike) -> _FloatArray:
        """Joint torques τ = H q̈ + C q̇ + g (recursive Newton–Euler), with the true Coriolis torque.

        ``q``, ``qd``, ``qdd``: shape (dof,) or (N, dof). Returns (dof,) or (N, dof).
        """

    def bias_torques(self, q: _ArrayLike, qd: _ArrayLike, formulation: _Formulation = "euler_lagrange") -> _FloatArray:
        """Bias torques C(q, q̇) q̇ + g(q) of the chosen formulation.

        ``q``, ``qd``: shape (dof,) or (N, dof). Returns (dof,) or (N, dof).
        """

    def forward_dynamics(self, q: _ArrayLike, qd: _ArrayLike, tau: _ArrayLike, formulation: _Formulation = "euler_lagrange") -> _FloatArray:
        """Joint accelerations q̈ = H⁻¹ (τ − C q̇ − g) with the chosen formulation's C.

        ``q``, ``qd``, ``tau``: shape (dof,) or (N, dof). Returns (dof,) or (N, dof).
        Raises DynamicsError if an input is not finite or H is not positive definite.
        """

    def kinetic_energy(self, q: _ArrayLike, qd: _ArrayLike) -> float | _FloatArray:
        """Kinetic energy ½ q̇ᵀ H q̇ [J]: a float for one state, shape (N,) for a batch."""

    def potential_energy(self, q: _ArrayLike) -> float | _FloatArray:
        """Potential energy of gravity U(q) [J] (g = ∂U/∂q): a float for one state, shape (N,) for a batch."""

    def dynamics_terms(self, q: _ArrayLike, qd: _ArrayLike, formulation: _Formulation = "euler_lagrange") -> tuple[_FloatArray, _FloatArray, _FloatArray]:
        """H(q), C(q, q̇) and g(q) in one call, cheaper than three calls.

        ``q``, ``qd``: shape (dof,) or (N, dof). Returns ``(H, C, g)`` with shapes
        ((dof, dof), (dof, dof), (dof,)) or ((N, dof, dof), (N, dof, dof), (N, dof)).
        """
