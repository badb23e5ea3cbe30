//! Errors of `simgap-core`.

use std::path::PathBuf;

/// Everything that can go wrong while building a [`Model`](crate::Model).
///
/// Every variant says where (`source`: the file, or `<string>` / `<code>`), which element, and
/// what was expected.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The file could not be read.
    #[error("{path}: cannot read file: {cause}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error (in the message, not a separate source, so it is said once).
        cause: std::io::Error,
    },
    /// The document is not well-formed URDF XML.
    #[error("{source_name}: malformed URDF: {message}")]
    MalformedUrdf {
        /// File name or `<string>`.
        source_name: String,
        /// What the parser said.
        message: String,
    },
    /// Elements nest deeper than any URDF does (refused before parsing: the XML readers recurse
    /// once per level).
    #[error("{source_name}: elements nest {depth} levels deep (more than {limit} from line {line} on); expected a URDF, whose elements nest a handful of levels (robot > link > visual > geometry > mesh)")]
    TooDeep {
        /// File name.
        source_name: String,
        /// The deepest nesting found.
        depth: usize,
        /// The most levels accepted.
        limit: usize,
        /// Line where the nesting first exceeds the limit.
        line: u32,
    },
    /// An unexpanded xacro element or expression.
    #[error("{source_name}: line {line}: {}; expected plain URDF: run xacro first (xacro robot.urdf.xacro > robot.urdf)", xacro_found(.element, .attribute, .value))]
    Xacro {
        /// File name.
        source_name: String,
        /// Line of the element.
        line: u32,
        /// The element's tag.
        element: String,
        /// The attribute holding the expression; empty when the element itself is a xacro one.
        attribute: String,
        /// The attribute's value.
        value: String,
    },
    /// A number attribute that is not a number.
    #[error("{source_name}: line {line}: {element} has {attribute}=\"{value}\"; expected {}", expected_numbers(*.count))]
    BadNumber {
        /// File name.
        source_name: String,
        /// Line of the element.
        line: u32,
        /// The element and the link or joint it belongs to, e.g. `<mass> of link 'forearm'`.
        element: String,
        /// The attribute.
        attribute: &'static str,
        /// The text found.
        value: String,
        /// How many numbers the attribute holds.
        count: u8,
    },
    /// The `<robot>` element has no `<link>`.
    #[error("{source_name}: <robot> has no <link> element; expected at least one link, and joints connecting them")]
    NoLinks {
        /// File name.
        source_name: String,
    },
    /// A link name appears twice.
    #[error("{source_name}: link '{link}' is defined more than once; expected unique link names")]
    DuplicateLink {
        /// File name.
        source_name: String,
        /// The repeated name.
        link: String,
    },
    /// A joint name appears twice.
    #[error("{source_name}: joint '{joint}' is defined more than once; expected unique joint names")]
    DuplicateJoint {
        /// File name.
        source_name: String,
        /// The repeated name.
        joint: String,
    },
    /// A joint refers to a link that does not exist.
    #[error("{source_name}: joint '{joint}' names {role} link '{link}', which is not defined; expected the name of a <link> in the file")]
    MissingLink {
        /// File name.
        source_name: String,
        /// The joint.
        joint: String,
        /// `parent` or `child`.
        role: &'static str,
        /// The missing link.
        link: String,
    },
    /// The kinematic graph has a loop or a link with two parents.
    #[error("{source_name}: link '{link}' {detail}; expected a tree (each link the child of at most one joint, no loops)")]
    Loop {
        /// File name.
        source_name: String,
        /// A link on the loop.
        link: String,
        /// What was found.
        detail: String,
    },
    /// The model is not a tree with a single root.
    #[error("{source_name}: expected exactly one root link (a link that is no joint's child), found {found:?}")]
    Roots {
        /// File name.
        source_name: String,
        /// The roots that were found.
        found: Vec<String>,
    },
    /// The movable joints branch and no tip link was chosen.
    #[error("{source_name}: the chain is not serial: link '{link}' has movable branches through {children:?}; choose a tip link (tip / --tip)")]
    NotSerial {
        /// File name.
        source_name: String,
        /// Where the tree branches.
        link: String,
        /// The branches.
        children: Vec<String>,
    },
    /// The requested tip link does not exist.
    #[error("{source_name}: tip link '{tip}' is not defined")]
    UnknownTip {
        /// File name.
        source_name: String,
        /// The requested tip.
        tip: String,
    },
    /// No revolute, continuous or prismatic joint between root and tip.
    #[error("{source_name}: no movable joint between root '{root}' and tip '{tip}'; expected at least one revolute, continuous or prismatic joint")]
    NoMovableJoint {
        /// File name.
        source_name: String,
        /// Root link.
        root: String,
        /// Tip link.
        tip: String,
    },
    /// A joint type this crate does not model.
    #[error("{source_name}: joint '{name}' has unsupported type '{kind}'; expected revolute, continuous, prismatic or fixed")]
    UnsupportedJoint {
        /// File name.
        source_name: String,
        /// The joint.
        name: String,
        /// Its type.
        kind: String,
    },
    /// A joint axis of zero length.
    #[error("{source_name}: joint '{joint}' has a zero-length axis {axis:?}; expected a non-zero direction")]
    ZeroAxis {
        /// File name.
        source_name: String,
        /// The joint.
        joint: String,
        /// The axis as written.
        axis: [f64; 3],
    },
    /// A number is NaN or infinite.
    #[error("{source_name}: {element} has a non-finite value in {field} ({value}); expected a finite number")]
    NonFinite {
        /// File name.
        source_name: String,
        /// e.g. `link 'forearm'` or `joint 'elbow'`.
        element: String,
        /// The attribute.
        field: String,
        /// The value read.
        value: f64,
    },
    /// A number finite but so large that the dynamics overflow with it: a length whose square
    /// times a mass leaves `f64` (see [`MAX_URDF_MAGNITUDE`](crate::urdf::MAX_URDF_MAGNITUDE)).
    #[error("{source_name}: {element} has {value:e} in {field}; expected a number of magnitude at most {limit:e} (larger ones overflow the dynamics)")]
    TooLarge {
        /// File name.
        source_name: String,
        /// e.g. `link 'forearm'` or `joint 'elbow'`.
        element: String,
        /// The attribute.
        field: String,
        /// The value read.
        value: f64,
        /// The largest magnitude accepted.
        limit: f64,
    },
    /// A link with negative mass.
    #[error("{source_name}: link '{link}' has mass {mass}; expected mass >= 0")]
    NegativeMass {
        /// File name.
        source_name: String,
        /// The link.
        link: String,
        /// The mass.
        mass: f64,
    },
    /// A rotational inertia that no rigid body can have.
    #[error("{source_name}: link '{link}' has a non-physical inertia: {detail}")]
    NonPhysicalInertia {
        /// File name.
        source_name: String,
        /// The link.
        link: String,
        /// What is wrong (eigenvalues, triangle inequality).
        detail: String,
    },
    /// Every link of the chain is massless.
    #[error("{source_name}: every link between root and tip is massless ({links:?}); expected at least one <inertial> with mass > 0")]
    Massless {
        /// File name.
        source_name: String,
        /// The massless links of the chain.
        links: Vec<String>,
    },
    /// A model built in code is inconsistent.
    #[error("invalid model: {0}")]
    InvalidModel(String),
}

fn expected_numbers(count: u8) -> String {
    if count == 1 {
        "a number".into()
    } else {
        format!("{count} numbers separated by spaces")
    }
}

fn xacro_found(element: &str, attribute: &str, value: &str) -> String {
    if attribute.is_empty() {
        format!("<{element}> is an unexpanded xacro element")
    } else {
        format!("<{element}> attribute {attribute}=\"{value}\" is an unexpanded xacro expression")
    }
}

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
