//! ROS 2 MCAP logs: what rosbag2 writes, and what simgap writes so that rosbag2, rosbags,
//! `mcap_ros2` and Foxglove read it.
//!
//! - Every channel is a `cdr`-encoded ROS 2 message with its `ros2msg` schema (the concatenated
//!   definition rosbag2 writes) and `offered_qos_profiles` channel metadata; the file claims the
//!   `ros2` profile. Run status and the experiment go in metadata records, never in a channel.
//! - `/joint_states`, `/joint_reference`, `/joint_effort_measured`: `sensor_msgs/msg/JointState`
//!   (see [`crate::topics`] for what each holds and how to map other topics and types).
//! - `simgap.experiment` metadata record: the experiment (`controller`, `joints`, `kp`, `kv`,
//!   `sample_period`); `simgap.run_end`: how a simulated run ended.
//!
//! One job per file: [`cdr`] (the wire format), [`schema`] (definitions and a decoder driven by
//! them), [`scan`] (the bounded record scan), [`merge`] (messages into samples), [`read`] (a
//! file or bag into a run), [`write`] (the sink and whole-run writer), [`chunked`] (the file
//! the sink's thread writes from whole chunks).

pub mod cdr;
pub(crate) mod chunked;
pub(crate) mod merge;
pub(crate) mod read;
pub mod scan;
pub mod schema;
pub mod write;

pub use cdr::{CdrError, JointState};
pub use schema::{Schema, Value};
pub use write::{McapSink, McapWriter, RunTopics, SinkOptions};

pub use crate::topics::{JOINT_EFFORT_MEASURED_TOPIC, JOINT_REFERENCE_TOPIC, JOINT_STATES_TOPIC};

/// Name of the experiment metadata record.
pub const EXPERIMENT_METADATA: &str = "simgap.experiment";
/// Name of the run-end metadata record written by [`McapSink`](crate::McapSink) (`status`:
/// `completed`, `interrupted` or `diverged`; `t` [s since the start]; `joint` when diverged).
pub const RUN_END_METADATA: &str = "simgap.run_end";
/// Schema name of `sensor_msgs/msg/JointState`.
pub const JOINT_STATE_SCHEMA: &str = "sensor_msgs/msg/JointState";
/// Schema encoding of ROS 2 message definitions.
pub const ROS2MSG_ENCODING: &str = "ros2msg";
/// Message encoding of ROS 2 messages.
pub const CDR_ENCODING: &str = "cdr";

/// The concatenated definition of `sensor_msgs/msg/JointState` as rosbag2 writes it.
pub const JOINT_STATE_DEFINITION: &str = "\
# This is a message that holds data to describe the state of a set of torque controlled joints.
#
# The state of each joint (revolute or prismatic) is defined by:
#  * the position of the joint (rad or m),
#  * the velocity of the joint (rad/s or m/s) and
#  * the effort that is applied in the joint (Nm or N).
#
# Each joint is uniquely identified by its name
# The header specifies the time at which the joint states were recorded. All the joint states
# in one message have to be recorded at the same time.
#
# This message consists of a multiple arrays, one for each part of the joint state.
# The goal is to make each of the fields optional. When e.g. your joints have no
# effort associated with them, you can leave the effort array empty.
#
# All arrays in this message should have the same size, or be empty.
# This is the only way to uniquely associate the joint name with the correct
# states.

std_msgs/Header header

string[] name
float64[] position
float64[] velocity
float64[] effort

================================================================================
MSG: std_msgs/Header
# Standard metadata for higher-level stamped data types.
# This is generally used to communicate timestamped data
# in a particular coordinate frame.

# Two-integer timestamp that is expressed as seconds and nanoseconds.
builtin_interfaces/Time stamp

# Transform frame with which this data is associated.
string frame_id

================================================================================
MSG: builtin_interfaces/Time
# This message communicates ROS Time defined here:
# https://design.ros2.org/articles/clock_and_time.html

# The seconds component, valid over all int32 values.
int32 sec

# The nanoseconds component, valid in the range [0, 1e9), to be added to the seconds component.
# e.g.
# The time -1.7 seconds is represented as {sec: -2, nanosec: 3e8}
# The time 1.7 seconds is represented as {sec: 1, nanosec: 7e8}
uint32 nanosec
";

/// The `offered_qos_profiles` channel metadata rosbag2 writes for a reliable, volatile topic.
pub(crate) const OFFERED_QOS_PROFILES: &str = "- history: 3
  depth: 0
  reliability: 1
  durability: 2
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: 1
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false";

/// The definition of `std_msgs/msg/Float64MultiArray` (for files that store none).
pub const FLOAT64_MULTI_ARRAY_DEFINITION: &str = "\
MultiArrayLayout layout
float64[] data
================================================================================
MSG: std_msgs/MultiArrayLayout
MultiArrayDimension[] dim
uint32 data_offset
================================================================================
MSG: std_msgs/MultiArrayDimension
string label
uint32 size
uint32 stride
";

/// `pkg/msg/Type` as `pkg/Type`.
pub(crate) fn normalised_type(name: &str) -> String {
    name.replacen("/msg/", "/", 1)
}
