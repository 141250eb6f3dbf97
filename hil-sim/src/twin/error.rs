//! Errors of the digital twin: bad scene or rig descriptions, bad mesh files,
//! failed output files.

use std::path::PathBuf;

/// Everything that can go wrong while building or rendering a twin scene.
#[derive(Debug, thiserror::Error)]
pub enum TwinError {
    /// A camera index that the rig does not have.
    #[error("camera index {index} out of range: the rig has {count} cameras")]
    NoSuchCamera {
        /// Requested index.
        index: usize,
        /// Cameras in the rig.
        count: usize,
    },
    /// More or fewer projector timelines than the rig has projectors.
    #[error("{given} projector timelines given but the rig has {expected} projectors")]
    TimelineCount {
        /// Timelines passed in.
        given: usize,
        /// Projectors in the rig.
        expected: usize,
    },
    /// A pattern whose size differs from its projector's DMD.
    #[error("pattern is {got_w}x{got_h} but projector {projector} is {want_w}x{want_h}")]
    PatternSize {
        /// Projector index.
        projector: usize,
        /// Pattern width in pixels.
        got_w: u32,
        /// Pattern height in pixels.
        got_h: u32,
        /// DMD width in pixels.
        want_w: u32,
        /// DMD height in pixels.
        want_h: u32,
    },
    /// A pattern buffer whose length does not match its stated size.
    #[error("pattern buffer has {len} values, {width}x{height} needs {}", *width as usize * *height as usize)]
    PatternBuffer {
        /// Buffer length.
        len: usize,
        /// Stated width.
        width: u32,
        /// Stated height.
        height: u32,
    },
    /// A time interval that is empty, reversed or not finite.
    #[error("bad time interval [{start_s}, {end_s}] s")]
    BadInterval {
        /// Start in seconds.
        start_s: f64,
        /// End in seconds.
        end_s: f64,
    },
    /// A numeric parameter outside its valid range (NaN, negative, zero size).
    #[error("parameter `{name}` = {value} is invalid: {why}")]
    BadParameter {
        /// Parameter name.
        name: &'static str,
        /// Offending value.
        value: f64,
        /// What it must satisfy.
        why: &'static str,
    },
    /// An unknown built-in scene name.
    #[error("no built-in scene named `{0}` (see `hil-sim scenes`)")]
    UnknownScene(String),
    /// A mesh file that could not be parsed.
    #[error("mesh file {path}: {why}")]
    MeshParse {
        /// File path.
        path: PathBuf,
        /// What was wrong (line or byte offset included where known).
        why: String,
    },
    /// A mesh with no triangles or with indices pointing past its vertices.
    #[error("mesh has {triangles} triangles, {vertices} vertices, bad index {bad_index:?}")]
    BadMesh {
        /// Triangle count.
        triangles: usize,
        /// Vertex count.
        vertices: usize,
        /// First index past the vertex list, if any.
        bad_index: Option<u32>,
    },
    /// Reading or writing a file failed.
    #[error("i/o on {path}: {source}")]
    Io {
        /// File path.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// Encoding a PNG failed.
    #[error("png {path}: {source}")]
    Png {
        /// File path.
        path: PathBuf,
        /// Underlying error.
        source: image::ImageError,
    },
}

impl TwinError {
    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> TwinError {
        let path = path.into();
        move |source| TwinError::Io { path, source }
    }
}

/// Checks that `value` is finite and strictly positive.
pub(crate) fn positive(name: &'static str, value: f64) -> Result<f64, TwinError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(TwinError::BadParameter {
            name,
            value,
            why: "must be finite and > 0",
        })
    }
}

/// Checks that `value` is finite and not negative.
pub(crate) fn non_negative(name: &'static str, value: f64) -> Result<f64, TwinError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(TwinError::BadParameter {
            name,
            value,
            why: "must be finite and >= 0",
        })
    }
}
