//! The crate's one error type. Every fallible public function returns [`Result<T>`]; the Python
//! bindings map each variant to a Python exception class (subclasses of `ValueError`,
//! `OSError` or `RuntimeError`), so no error crosses the boundary as a panic.

use thiserror::Error;

/// Everything that can go wrong in FoldMatch, with enough context to find the culprit.
#[derive(Debug, Error)]
pub enum FoldMatchError {
    /// An array argument has the wrong shape or is empty.
    #[error("{name}: {reason}")]
    Shape {
        /// Argument name, e.g. `template_vertices`.
        name: String,
        /// What was expected and what was found.
        reason: String,
    },
    /// A coordinate is NaN or infinite.
    #[error("{name}: non-finite coordinate at row {row} ({value})")]
    NonFinite {
        /// Argument name.
        name: String,
        /// Index of the offending row (vertex / point).
        row: usize,
        /// The offending value.
        value: f64,
    },
    /// A face refers to a vertex that does not exist.
    #[error("{name}: face {face} refers to vertex {vertex}, but there are only {count} vertices")]
    FaceIndex {
        /// Argument name.
        name: String,
        /// Face index.
        face: usize,
        /// The out-of-range vertex index.
        vertex: i64,
        /// Number of vertices.
        count: usize,
    },
    /// A landmark is invalid: its vertex index is out of range or used twice, or its target
    /// position is not finite.
    #[error("landmark {index}: {reason}")]
    Landmark {
        /// The landmark's position in the given list (0-based).
        index: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// A parameter is out of its valid range.
    #[error("parameter {name} = {value}: {reason}")]
    Parameter {
        /// Parameter name.
        name: String,
        /// The value given, formatted.
        value: String,
        /// The valid range.
        reason: String,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A file was read but its content is malformed.
    #[error("{path}:{line}: {reason}")]
    Format {
        /// The file.
        path: String,
        /// 1-based line number (0 when not applicable, e.g. binary payloads).
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// The template lies far from the scan (a units or placement mistake, most likely).
    #[error(
        "the template's centroid is {distance:.2} target bounding-box diagonals from the scan's \
         centroid: check units or pre-align it (prealign = \"rigid\")"
    )]
    FarAway {
        /// Centroid distance in target diagonals.
        distance: f64,
    },
    /// The template and the scan differ in size by more than a rigid pre-alignment can place
    /// (a units mistake, most likely).
    #[error(
        "the template's bounding-box diagonal is {ratio:.3} times the scan's: check units, or \
         pre-align with a scale (prealign = \"similarity\")"
    )]
    SizeMismatch {
        /// Template diagonal ÷ scan diagonal.
        ratio: f64,
    },
    /// The fit was stopped by the user's callback or an interrupt.
    #[error("fit cancelled after {iterations} iterations")]
    Cancelled {
        /// Iterations completed before the stop.
        iterations: usize,
    },
    /// The computation diverged (non-finite positions).
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// Memory for a size the input announced could not be allocated (the sizes are checked
    /// against the input and the limits of [`crate::limits`] first, so this is a machine with
    /// less memory than the input needs).
    #[error("{what}: cannot allocate {bytes} bytes (out of memory)")]
    OutOfMemory {
        /// What the memory was for (and the file it comes from, when there is one).
        what: String,
        /// The bytes asked for.
        bytes: usize,
    },
}

/// Shorthand for `std::result::Result<T, FoldMatchError>`.
pub type Result<T> = std::result::Result<T, FoldMatchError>;

impl FoldMatchError {
    /// Convenience constructor for [`FoldMatchError::Parameter`].
    pub fn parameter(name: &str, value: impl std::fmt::Display, reason: &str) -> Self {
        Self::Parameter {
            name: name.into(),
            value: value.to_string(),
            reason: reason.into(),
        }
    }
    /// Convenience constructor for [`FoldMatchError::OutOfMemory`].
    pub fn out_of_memory(what: &str, bytes: usize) -> Self {
        Self::OutOfMemory {
            what: what.into(),
            bytes,
        }
    }
    /// Convenience constructor for [`FoldMatchError::Shape`].
    pub fn shape(name: &str, reason: impl Into<String>) -> Self {
        Self::Shape {
            name: name.into(),
            reason: reason.into(),
        }
    }
}
