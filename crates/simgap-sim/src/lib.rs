//! Closed-loop simulation of serial manipulators sampled like a real controller, the run type
//! every log reader fills, and the L² index. Reading and writing log files is the job of the
//! `simgap-log` crate: the simulator and its tests never touch a file format.

pub mod backlash;
pub mod controller;
pub mod delay;
pub mod effects;
pub mod error;
pub mod experiment;
pub mod integrate;
pub mod kind;
pub mod l2;
pub mod paper;
pub mod params;
pub mod plant;
pub mod reference;
pub mod run;
pub mod sensor;
pub mod simulate;
pub mod sink;
pub mod step;
pub mod substeps;

pub use error::{Error, Result};
pub use experiment::{experiment_from_map, experiment_to_map, ControllerKind, Experiment};
pub use run::{central_difference, fill_sample_period, hold_rows, interpolate_rows, reorder_joints, validate_run, DriveSample, DriveSignals, Run, Sample};
pub use sink::{MemorySink, RunEnd, Sink};

pub use controller::{controller_from_experiment, Controller, Pd, PdGravity, Replay, Servo, ZeroTorque};
pub use delay::DelayLine;
pub use effects::{applied_torque, friction_torque, typical_width, Effect, LinkDelta, DEFAULT_COULOMB_WIDTH, TYPICAL_WIDTH_PRISMATIC, TYPICAL_WIDTH_REVOLUTE};
pub use experiment::ServoParams;
pub use integrate::Integrator;
pub use kind::{EffectKind, ParamSpec, Quantity};
pub use l2::{l2_between, l2_index, l2_per_joint, l2_tracking, L2Accumulator, L2Report, TrackingL2Sink};
pub use params::{SimParams, DEFAULT_SUBSTEPS};
pub use plant::{Plant, PlantWorkspace};
pub use reference::{reference_from_run, reference_from_run_for, Fourier, PiecewiseSetpoints, Reference, Sampled, Step};
pub use sensor::{SensorParams, VelocityEstimate};
pub use simulate::{simulate, simulate_experiment, simulate_experiment_with_end};
pub use step::Stepper;
pub use substeps::{effective_substeps, resolvable_effects, unresolved_bands_exact};
