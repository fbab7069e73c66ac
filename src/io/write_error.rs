//! The error every mesh writer returns.
//!
//! Writers validate their whole input before the first byte goes out, so a
//! [`WriteError`] other than [`WriteError::Io`] means nothing was written and
//! the variant names what is wrong with the data (which node, which element,
//! which view). An `Io` error can happen mid-file: the output is then
//! truncated and must be discarded by the caller.

use thiserror::Error;

/// Why a mesh could not be written.
#[derive(Debug, Error)]
pub enum WriteError {
    /// The underlying writer failed (disk full, closed pipe, ...).
    #[error("write failed: {0}")]
    Io(#[from] std::io::Error),

    /// A tag that must be positive is zero or negative.
    #[error("{what} tag {tag} is not positive (tags start at 1)")]
    NonPositiveTag {
        /// What carries the tag ("node", "element", "curve", ...).
        what: &'static str,
        /// The offending tag.
        tag: i64,
    },

    /// Two items of the same kind share a tag.
    #[error("{what} tag {tag} is used twice")]
    DuplicateTag {
        /// What carries the tag ("node", "element", "point entity", ...).
        what: &'static str,
        /// The repeated tag.
        tag: u64,
    },

    /// An element names a node tag that no node block defines.
    #[error("element {element} refers to node {node}, which is not defined")]
    MissingNode {
        /// Element tag.
        element: u64,
        /// Missing node tag.
        node: u64,
    },

    /// Something refers to a model entity that is not defined.
    #[error("{referrer} refers to {dim}-dimensional entity {tag}, which is not defined")]
    MissingEntity {
        /// Who refers to it ("node block", "surface 3 boundary", ...).
        referrer: String,
        /// Entity dimension (0 point, 1 curve, 2 surface, 3 volume).
        dim: u8,
        /// Entity tag (absolute value).
        tag: i32,
    },

    /// An element type placed on an entity of another dimension.
    #[error(
        "element block of {element_type} (dimension {element_dim}) is placed on entity ({entity_dim}, {entity_tag})"
    )]
    DimensionMismatch {
        /// Element type name.
        element_type: &'static str,
        /// Dimension of that element type.
        element_dim: u8,
        /// Dimension of the entity the block is on.
        entity_dim: u8,
        /// Tag of that entity.
        entity_tag: i32,
    },

    /// An array does not have the length its counterpart implies.
    #[error("{what}: expected {expected} values, got {got}")]
    LengthMismatch {
        /// Which array ("node block (2, 1) positions", "view \"sigma\" values", ...).
        what: String,
        /// Expected length.
        expected: usize,
        /// Actual length.
        got: usize,
    },

    /// A data view has a number of components the format cannot hold.
    #[error("view \"{view}\" has {n_components} components; {allowed}")]
    BadComponents {
        /// View name.
        view: String,
        /// Components per value.
        n_components: usize,
        /// What the format accepts.
        allowed: &'static str,
    },

    /// A data view names a node or element tag the model does not have.
    #[error("view \"{view}\" has a value for {what} {tag}, which is not defined")]
    UnknownDataTag {
        /// View name.
        view: String,
        /// "node" or "element".
        what: &'static str,
        /// The unknown tag.
        tag: u64,
    },

    /// A name that cannot be written as a quoted string.
    #[error("name {name:?} contains a quote or a line break")]
    BadName {
        /// The offending name.
        name: String,
    },

    /// A coordinate is NaN or infinite.
    #[error("{what} has a non-finite coordinate ({x}, {y}, {z})")]
    NonFiniteCoordinate {
        /// Which point ("node 12", "parametrization of surface 3, point 7", ...).
        what: String,
        /// x.
        x: f64,
        /// y.
        y: f64,
        /// z.
        z: f64,
    },

    /// A cell or triangle refers to a point index out of range.
    #[error("{what} refers to point {index}, but there are only {n_points}")]
    IndexOutOfRange {
        /// Which cell ("triangle 5", "parametrization of surface 2, triangle 9", ...).
        what: String,
        /// The index (0-based).
        index: u64,
        /// Number of points.
        n_points: usize,
    },

    /// The model is structurally invalid in a way not covered above.
    #[error("invalid model: {0}")]
    Invalid(String),

    /// More items than the format can count.
    #[error("{what}: {count} exceeds the format's limit of {max}")]
    TooLarge {
        /// What is counted.
        what: &'static str,
        /// How many there are.
        count: usize,
        /// The limit.
        max: u64,
    },
}
