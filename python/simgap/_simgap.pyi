"""The simgap extension module (Rust). Import from :mod:`simgap` instead."""

from os import PathLike
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Literal, TypeAlias, final

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

@final
class Run:
    """A run of a robot or a simulation: time, measured and reference signals, and the experiment
    (controller, gains, sample period) that produced it.

    Matrices have shape (N, dof) with columns in ``joints`` order, as C-ordered float64 arrays.
    """

    def __new__(
        cls,
        joints: list[str],
        t: _ArrayLike,
        q: _ArrayLike,
        qd: _ArrayLike,
        tau: _ArrayLike | None = None,
        q_ref: _ArrayLike | None = None,
        qd_ref: _ArrayLike | None = None,
        experiment: dict[str, str] | None = None,
        source: str = "python",
        tau_ff: _ArrayLike | None = None,
        tau_measured: _ArrayLike | None = None,
        start_ns: int | None = None,
        duty: _ArrayLike | None = None,
        torque_enable: _ArrayLike | None = None,
        voltage: _ArrayLike | None = None,
        temperature: _ArrayLike | None = None,
    ) -> Run:
        """Builds a run from arrays; ``joints`` names the columns.

        ``t``: shape (N,); ``q``, ``qd`` and the optional ``tau``, ``q_ref``, ``qd_ref``,
        ``tau_ff``, ``tau_measured``: shape (N, len(joints)). ``experiment`` is the
        ``simgap.experiment`` metadata map (``controller``, ``joints``, ``kp``, ``kv``,
        ``sample_period``, as strings); ``start_ns`` the absolute time of ``t = 0`` [ns since
        the Unix epoch]. A position-controlled servo's signals: ``duty`` (PWM duty in [−1, 1]),
        ``torque_enable`` (0/1) and ``temperature`` [°C], shape (N, len(joints)), and
        ``voltage`` [V], shape (N,).

        Raises DimensionError for arrays of the wrong shape, LogError for an invalid run (time
        not strictly increasing, non-finite values, duplicate joints, a bad experiment).
        """

    @property
    def joints(self) -> list[str]:
        """Joint names: the column order of every matrix."""

    @property
    def dof(self) -> int:
        """Number of joints."""

    @property
    def t(self) -> _FloatArray:
        """Sample times [s], shape (N,): time since the log's start (see ``start_ns``)."""

    @property
    def q(self) -> _FloatArray:
        """Measured positions [rad or m], shape (N, dof)."""

    @property
    def qd(self) -> _FloatArray:
        """Measured velocities (as the controller saw them) [rad/s or m/s], shape (N, dof)."""

    @property
    def tau(self) -> _FloatArray | None:
        """Commanded torques [N·m or N], shape (N, dof); None when the log has no effort."""

    @property
    def q_ref(self) -> _FloatArray | None:
        """Reference positions, shape (N, dof); None when the run has no reference."""

    @property
    def qd_ref(self) -> _FloatArray | None:
        """Reference velocities, shape (N, dof); None when absent (zero)."""

    @property
    def tau_ff(self) -> _FloatArray | None:
        """Feed-forward torques the controller adds to its feedback [N·m or N] (the effort of the
        reference topic), shape (N, dof); None when absent (zero)."""

    @property
    def tau_measured(self) -> _FloatArray | None:
        """Torques the drives report delivering [N·m or N] (``/joint_effort_measured``), shape
        (N, dof); None when the log has none."""

    @property
    def duty(self) -> _FloatArray | None:
        """A servo's measured PWM duty in [−1, 1], shape (N, dof); None when the log has none."""

    @property
    def torque_enable(self) -> _FloatArray | None:
        """A servo's torque enable (0 or 1), shape (N, dof); None when the log has none."""

    @property
    def voltage(self) -> _FloatArray | None:
        """A servo's supply voltage [V], shape (N,); None when the log has none."""

    @property
    def temperature(self) -> _FloatArray | None:
        """A servo's temperature [°C], shape (N, dof); None when the log has none."""

    @property
    def start_ns(self) -> int | None:
        """Absolute time of ``t = 0`` [ns since the Unix epoch] for logs with absolute stamps,
        else None."""

    @property
    def experiment(self) -> dict[str, str] | None:
        """The ``simgap.experiment`` metadata as a dict of strings, or None."""

    @property
    def source(self) -> str:
        """Where the run came from (file name, or "simulation")."""

    @property
    def notes(self) -> list[str]:
        """What the log's reader noted for a report (e.g. that a LeRobot dataset's timestamps
        are nominal), one sentence each; a diagnosis puts them in its notes."""

    @property
    def left_out(self) -> list[str]:
        """Joints the log records but not as positions a model can use (a LeRobot joint
        range-normalised without its calibration file): not in ``joints``; a diagnosis locks a
        model joint of that name at its zero position."""

    @property
    def duration(self) -> float:
        """Duration [s]: last sample time minus first (0 for fewer than two samples)."""

    def __len__(self) -> int:
        """Number of samples."""

@final
class L2Report:
    """L² indices of a difference signal (the seed paper's eq. 127)."""

    @property
    def joints(self) -> list[str]:
        """Joint names (the order of the per-joint arrays)."""

    @property
    def overall(self) -> float:
        """L² of the whole difference vector [rad or m]."""

    @property
    def per_joint(self) -> _FloatArray:
        """L² of each joint, shape (dof,)."""

    @property
    def max_abs_per_joint(self) -> _FloatArray:
        """Maximum absolute difference of each joint, shape (dof,)."""

    @property
    def span(self) -> tuple[float, float]:
        """Time span used, (start, end) [s]."""

    @property
    def samples(self) -> int:
        """Number of samples used."""

def read_log(
    path: str | PathLike[str],
    joints: list[str] | None = None,
    topics: dict[str, str] | None = None,
    experiment: dict[str, str] | None = None,
    calibration: str | PathLike[str] | None = None,
) -> Run:
    """Reads a log: a ROS 2 MCAP file (``.mcap``), a rosbag2 bag folder (``metadata.yaml`` and
    ``.mcap`` files), CSV (``.csv`` / ``.csv.gz``), or one episode of a LeRobot dataset
    (``FOLDER#N``; a folder or selection of several episodes is read with :func:`read_logs`).

    With ``joints`` (e.g. ``model.joint_names``), the columns are put in that order, matched by
    name (joints the log leaves out, ``Run.left_out``, are skipped). ``topics`` maps roles to
    topics, e.g. ``{"states": "/arm/joint_states", "effort":
    "/effort_controller/commands[j1;j2]"}`` (roles ``states``, ``reference``, ``effort``,
    ``measured_effort``; joint names in brackets for messages without names). ``experiment``
    (the ``simgap.experiment`` map) applies only if the log carries none (no metadata record,
    no sidecar ``NAME.experiment.json``, for a dataset ``meta/simgap.experiment.json``).
    ``calibration``: LeRobot's calibration file, which makes a dataset's range-normalised joint
    (a gripper's 0–100) an angle; without it that joint is left out. A file its recorder did
    not finish is read up to its last complete record, with a UserWarning saying how much was
    recovered. Raises LogError naming the file and the problem, for any content of the file.
    """

def read_logs(
    path: str | PathLike[str],
    joints: list[str] | None = None,
    topics: dict[str, str] | None = None,
    experiment: dict[str, str] | None = None,
    calibration: str | PathLike[str] | None = None,
) -> list[Run]:
    """Reads every run a log holds: one per episode of a LeRobot dataset (a folder means every
    episode, ``FOLDER#0,3-5`` those episodes, in that order; each run is named ``FOLDER#N``),
    else the one run of an MCAP file, bag folder or CSV file. The arguments are
    :func:`read_log`'s; a dataset's warnings are given once. Raises LogError naming the folder,
    the file and the episode."""

def lerobot_episodes(path: str | PathLike[str]) -> list[int]:
    """The episode indices of a LeRobot dataset folder, in order (``FOLDER#N`` reads episode
    ``N``). Raises LogError naming the folder and the metadata file at fault."""

def write_log(run: Run, path: str | PathLike[str]) -> None:
    """Writes a run as a log, the format chosen by extension (``.mcap``, ``.csv``, ``.csv.gz``;
    CSV logs get their experiment in a sidecar JSON file). Raises LogError."""

def l2(t: _ArrayLike, x: _ArrayLike) -> float:
    """The L² index (eq. 127): sqrt(1/(t_end − t_0) ∫ ‖x‖² dt), trapezoid rule.

    ``t``: sample times, shape (N,); ``x``: the signal, shape (N,) or (N, k). Zero for fewer
    than two samples.
    """

def effect_vocabulary() -> list[dict[str, Any]]:
    """Every effect of the vocabulary, in the documented order.

    Each entry is ``{"name": str, "whole_robot": bool, "parameters": [{"name": str,
    "quantity": str, "unit": {"revolute": str, "prismatic": str}, "neutral": float | None, "estimated": bool}]}``.
    ``neutral`` is the value at which the effect is absent (``None`` where there is none);
    ``estimated`` is false for values searched on a grid and for counts (no interval).
    """

def compare(a: Run, b: Run, window: tuple[float, float] | None = None) -> L2Report:
    """L² of the position difference a.q − b.q (eq. 127).

    ``b`` is linearly resampled onto ``a``'s times and joints are matched by name; only samples
    inside both runs and inside ``window = (start, end)`` [s] count. Raises LogError when a
    joint of ``a`` is not in ``b``, SimulationError when fewer than two samples remain.
    """

def l2_tracking(run: Run, window: tuple[float, float] | None = None) -> L2Report:
    """L² of a run's tracking error q_ref − q (eq. 127 as the paper uses it), optionally within
    ``window = (start, end)`` [s]. Raises SimulationError when the run has no reference."""

def simulate(
    model: Model,
    reference: Run | _ArrayLike,
    *,
    controller: Literal["pd", "pd_gravity", "replay", "servo"] | None = None,
    kp: _ArrayLike | None = None,
    kv: _ArrayLike | None = None,
    replay: Run | None = None,
    formulation: _Formulation = "euler_lagrange",
    effects: list[str] = ...,
    duration: float | None = None,
    sample_period: float | None = None,
    t0: float | None = None,
    q0: _ArrayLike | None = None,
    qd0: _ArrayLike | None = None,
    substeps: int = 1,
    integrator: Literal["rk4", "adaptive"] = "rk4",
    rtol: float = 1e-10,
    atol: float = 1e-10,
    counts_per_rev: float | None = ...,
    velocity: Literal["backward_difference", "exact"] = "backward_difference",
    noise_std: float = 0.0,
    seed: int = 0,
    coulomb_width: float = 0.01,
    torque_limits_from_model: bool = False,
    divergence_bound: float = 10000.0,
    experiment: Mapping[str, object] | str | PathLike[str] | None = None,
) -> Run:
    """Simulates the sampled closed loop and returns the run as a log would record it.

    The plant ``model`` (plus ``effects``) runs under a controller following ``reference``,
    sampled like a real controller (zero-order hold, encoder quantisation, backward-difference
    velocity), integrated by RK4. The run holds measured q and q̇ as the controller saw them,
    the commanded τ, and the reference.

    ``reference``: a target position, shape (dof,) (a step at t0; q̇_ref = 0), or a Run whose
    reference (else measured q) is followed, joints matched by name. With a Run, ``t0``,
    ``duration``, ``q0``, ``qd0``, the controller, its gains and the sample period default to
    the run's (its first sample, its experiment); otherwise t0 = 0, duration = 3 s, q0 = qd0 =
    0, sample period 2.5 ms.

    ``experiment``: a dict of the ``simgap.experiment`` keys (a sidecar's) or the path of an
    experiment file, in place of the reference run's: the controller, its gains or a servo's
    constants, the sample period.

    ``controller``: "pd" (τ = Kp(q_ref − q) + Kv(q̇_ref − q̇)), "pd_gravity" (plus the model's
    g(q)), "replay" (the logged effort of ``replay``, default the reference run, open loop) or
    "servo" (a position-controlled servo with the constants of the experiment,
    ``duty_gain``, ``max_duty``, ``supply_voltage``, ``kt``, ``R``, reading the reference run's
    logged torque enable and voltage, if any; the returned run holds its duty, torque enable
    and voltage besides the command τ = (kt/R) V duty).
    ``kp``, ``kv``: gains, shape (dof,), in model order. ``effects``: unmodelled effects in the
    CLI spelling, e.g. "viscous_friction:b=2.288,0.175", "coulomb_friction:fc=7.17,1.734;w=0.01".
    ``integrator``: "rk4" (``substeps`` steps per sample, raised automatically for stiff
    friction) or "adaptive" (Dormand–Prince with ``rtol``, ``atol``). ``counts_per_rev``:
    encoder resolution (default 1,024,000 counts per revolution; None = exact positions); ``velocity``: "backward_difference" or
    "exact"; ``noise_std``, ``seed``: Gaussian position noise. ``coulomb_width``: the width
    w of sign(q̇) ≈ tanh(q̇/w) [rad/s or m/s] for every dry friction spelled without its own
    ``w`` (0: the exact sign; a ``w`` in the spelling wins). ``divergence_bound``: |q̇| beyond which the run has diverged.

    The GIL is released while simulating; Ctrl-C stops the run at its next sample and raises
    KeyboardInterrupt. Raises SimulationError when the run diverges or a parameter is invalid,
    LogError when the reference or replay run does not match the model's joints,
    DimensionError for vectors of the wrong length. Ranges are checked at once, with the
    words of ``simgap simulate``: 1e-6 ≤ sample_period ≤ 1 s, 0 < duration ≤ 86400 s,
    1 ≤ substeps ≤ 10000, at most 1e9 integration steps, and at most 1e7 samples (the
    returned Run is held in memory; ``simgap simulate --out RUN.mcap`` writes longer runs as
    they go).
    """

_LogArg: TypeAlias = Run | str | PathLike[str]
"""A run in memory (from ``read_log`` or ``simulate``) or the path of a log to read."""

@final
class Report:
    """The result of :func:`diagnose`: the diagnosis report, with the runs behind its figures.

    Every dict attribute is the JSON report parsed afresh (``json.loads(report.to_json())``),
    so ``to_dict()`` has exactly the keys of the CLI's ``--json`` output; ``where`` (a Python
    keyword) is the ``location`` attribute, and ``report["where"]`` works for every key.
    Non-finite numbers are None.
    """

    @property
    def selected_effects(self) -> list[dict[str, Any]]:
        """Effects the diagnosis concludes explain the gap: dicts ``{effect, joints, parameters,
        uncertainty}``; empty when nothing significant remains."""
    @property
    def interval_variants(self) -> dict[str, list[dict[str, Any]]]:
        """The selected effects with the 95 % half-widths of each interval method on its own:
        ``{method: [effect dicts]}``; for a torque-residual fit ``block_bootstrap``,
        ``fold_jackknife``, ``resampling`` (the larger of the two, 1.96 σ), ``pipeline_error``
        (1.96 |b|, the pipeline's measured error), ``noise_resampling`` (1.96 σ_n, the scatter
        that error does not make) and ``pipeline_error_change`` (1.96 |δ|, how far ``b`` moves
        measured again from the corrected values): the report's ``uncertainty`` is
        |b| + 1.96 sqrt(σ_n² + δ²); ``spread_or_bias`` (1.96 max(σ, |b|), the rule before) and
        ``bias_corrected`` (the values less ``b``, with the ``resampling`` half-widths); for a
        fit by multiple shooting ``multiple_shooting``."""
    @property
    def candidates(self) -> list[dict[str, Any]]:
        """Every effect tried, ranked: dicts with ``rank``, ``effect``, ``joints``,
        ``parameters``, ``uncertainty``, ``cv_residual_reduction``, ``holdout_l2_after``,
        ``holdout_ratio``, ``selected``, ``reason``."""
    @property
    def gap(self) -> dict[str, Any]:
        """How far the gap shrinks: ``headline`` and ``headline_reason``, ``kstep`` (held-out
        k-step prediction error per horizon before and after, and the constant-velocity floor),
        ``holdout_l2_before``, ``holdout_l2_after``, ``ratio``, per joint and per run."""
    @property
    def alternatives(self) -> list[dict[str, Any]]:
        """Effect sets these data cannot tell apart from the selected one: ``{effects, why}``."""
    @property
    def notes(self) -> list[str]:
        """Warnings about the logs and the answer (glitches, inferred sensors, URDF pitfalls,
        what the residual still holds)."""
    @property
    def residual(self) -> list[dict[str, Any]]:
        """What is left after the selected effects, per joint: ``rms`` [N·m],
        ``share_of_torque``, ``phase_rms`` (forward, backward, near rest), ``explained_by`` (the
        share of the residual that follows position, velocity, acceleration, torque or time on
        held-out halves) and ``kind`` (``negligible``, ``noise-like`` or ``structured``)."""
    @property
    def location(self) -> dict[str, Any]:
        """Where the gap lies (the report's ``where``): ``per_joint`` shares, ``worst_segments``,
        residual ``correlations``."""
    @property
    def selection_log(self) -> list[dict[str, Any]]:
        """The stepwise selection, step by step."""
    @property
    def verdict(self) -> str:
        """One-sentence conclusion."""
    @property
    def formulation(self) -> str:
        """Formulation of C under test."""
    @property
    def joints(self) -> list[str]:
        """Joint names, model order."""
    @property
    def model(self) -> str:
        """Robot name."""
    @property
    def holdout(self) -> list[Run]:
        """Held-out runs as measured, aligned to the model's joints."""
    @property
    def holdout_nominal(self) -> list[Run | None]:
        """Closed-loop simulations of the held-out runs with the nominal model (None where one
        failed)."""
    @property
    def holdout_corrected(self) -> list[Run | None]:
        """Closed-loop simulations of the held-out runs with the selected effects added (None
        where one failed)."""
    def keys(self) -> list[str]:
        """The report's keys (``report[key]`` works for each, ``where`` included)."""
    def to_dict(self) -> dict[str, Any]:
        """The report as a dict with the keys of the CLI's ``--json`` output
        (``selected_effects``, ``candidates``, ``gap``, ``where``, ``verdict``, ...)."""
    def to_json(self) -> str:
        """The report as JSON text, the same as the CLI's ``--json`` output."""
    def to_html(self, path: str | PathLike[str]) -> None:
        """Writes the self-contained HTML report (verdict, tables, inline SVG plots of every
        held-out run) to ``path``, like the CLI's ``--html``. Raises LogError when it cannot."""
    def export_urdf(self, path: str | PathLike[str], urdf: str | PathLike[str] | None = None) -> str:
        """Writes the URDF the model was loaded from with the selected effects written in (the
        corrected ``<inertial>`` of every changed link, ``<dynamics damping friction>`` for
        viscous and Coulomb friction; every other byte kept) to ``path``, and the selected
        effects a URDF cannot hold (rotor inertia, torque gain, delay, ...) to
        ``path + ".effects.json"`` in the ``selected_effects`` form, each with a sentence on how
        to apply it (the CLI's ``--export-urdf``). ``urdf``: the URDF file the model was loaded
        from; default the one given to ``diagnose(..., urdf=...)``. Returns the sidecar's path.
        ``pinocchio.buildModelFromUrdf(path)`` loads the file as it is.

        Raises UrdfError when the URDF cannot be read or is not the model's, FitError when an
        effect cannot be written into it, SimgapError when a file cannot be written."""
    def export_mjcf(self, path: str | PathLike[str]) -> str:
        """Writes an MJCF of the corrected robot to ``path`` (body inertials; joint armature,
        damping, frictionloss, stiffness/springref; a motor per driven joint with gear and
        forcerange; ``<option timestep>`` = the logs' sample period, gravity, RK4), and
        the selected effects MJCF cannot hold (delay, Stribeck shape, offsets, ...) to
        ``path + ".effects.json"`` (the CLI's ``--export-mjcf``).
        ``mujoco.MjModel.from_xml_path(path)`` loads it as it is. Returns the sidecar's path.

        Raises FitError when an effect cannot be written, SimgapError when a file cannot be
        written or the logs have no sample period."""
    def summary(self) -> str:
        """The terminal summary the CLI prints."""
    def _repr_html_(self) -> str:
        """The HTML report as a string: a notebook (Jupyter, VS Code) shows it in place of the repr."""
    @property
    def fit_residuals(self) -> list[dict[str, Any]]:
        """The fit runs as the diagnosis saw them, for plots: one dict per run with ``log`` (its
        name), ``t`` (N,) [s], and (N, dof) arrays ``q``, ``qd``, ``qdd`` (smoothed) and
        ``residual``, the nominal torque residual τ_cmd − (H q̈ + C q̇ + g) [N·m]."""
    def __getitem__(self, key: str, /) -> Any:
        """A report key, as in the JSON (``report["where"]``). Raises KeyError."""
    def __contains__(self, key: str, /) -> bool:
        """Whether the report has ``key``."""

DIAGNOSE_SWITCHES: list[tuple[str, bool, str]]
"""Every yes/no option of :func:`diagnose` as ``(name, default, help)``: its keywords, the CLI's
flags (``name`` with ``-`` for ``_``) and the fleet's options are this table."""

def diagnose(
    model: Model,
    fit: Sequence[_LogArg] | _LogArg,
    holdout: Sequence[_LogArg] | _LogArg,
    *,
    formulation: _Formulation = "euler_lagrange",
    experiment: Mapping[str, object] | str | PathLike[str] | None = None,
    progress: Callable[[str, int, int], object] | None = None,
    urdf: str | PathLike[str] | None = None,
    calibration: str | PathLike[str] | None = None,
    directional_friction: bool = False,
    load_stribeck_friction: bool = False,
    link_side_torque: bool = False,
) -> Report:
    """Diagnoses the gap between ``model`` and logged runs (the ``simgap diagnose`` pipeline):
    **where** the gap lies, **which** unmodelled effect causes it, and **how far** it shrinks
    on held-out runs once that effect is added.

    ``fit``: runs used to fit and select effects; ``holdout``: runs used only to measure the
    gap before and after (never for fitting). Each is a sequence of :class:`Run` (from
    ``read_log``, ``read_logs`` or ``simulate``) or paths to logs (read like ``read_logs``: a
    LeRobot dataset path, ``FOLDER`` or ``FOLDER#0,3-5``, gives one run per episode), or a
    single one.
    Every run must carry its experiment (controller, gains, sample period) to be re-simulated
    in closed loop. ``formulation``: the C of the model under test.

    ``urdf``: the URDF file ``model`` was loaded from, kept for :meth:`Report.export_urdf`.
    ``calibration``: LeRobot's calibration file, which makes a dataset's range-normalised joint
    (a gripper's 0–100) an angle; a model joint the logs leave out without one
    (``Run.left_out``) is locked at its zero position, and the report's notes say so.
    The keywords after it are the diagnosis' switches, one per entry of
    :data:`DIAGNOSE_SWITCHES` (the CLI's flags); another keyword raises TypeError.
    ``directional_friction``: also try friction that differs with the direction of motion in
    place of each joint's Coulomb and viscous friction (the CLI's ``--directional-friction``).
    ``load_stribeck_friction``: on servo logs, also try the servo's load friction rising at
    rest, a breakaway level above the moving one (the CLI's ``--load-stribeck-friction``).
    ``link_side_torque``: the logged effort is measured on the link side of the gearbox
    (joint-torque sensors), so no rotor inertia or back-EMF is tried (``--link-side-torque``).

    ``experiment``: the experiment of runs that carry none (a recorded bag, a CSV log without
    sidecar): a ``simgap.experiment`` metadata dict (``controller``, ``joints``, ``kp``,
    ``kv``, ``sample_period``, as ``Run.experiment`` gives it) or the path of an experiment
    JSON file. ``progress``: called on the calling thread as ``progress(stage, done, total)``
    whenever the diagnosis moves on (at most every 50 ms); an exception from it stops the
    diagnosis and is raised. ``simgap.diagnose(..., progress=True)`` shows a tqdm bar.

    Runs on its own thread with the GIL released; Ctrl-C raises KeyboardInterrupt. Raises
    FitError when there is no fit or held-out run, a log is given as both, or the fit fails;
    LogError when a log cannot be read, lacks a model joint or its experiment, or is too short;
    TypeError for arguments that are neither runs nor paths.

    Example::

        report = simgap.diagnose(model, ["fit1.mcap", "fit2.mcap"], ["held.mcap"])
        print(report.summary())
        report.selected_effects   # [{"effect": <an effect name>, "joints": [...], ...}]
        report.gap["holdout_l2_after"] < report.gap["holdout_l2_before"]
        report.to_html("report.html")
    """
