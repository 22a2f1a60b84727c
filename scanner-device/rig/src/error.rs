//! Why a rig could not be built or a frame rendered.

use scanner_core::GeomError;

/// Why a rig could not be built or a frame rendered.
#[derive(Debug, thiserror::Error)]
pub enum RigError {
    /// A scene value is out of range; the text names it.
    #[error("bad scene: {0}")]
    Scene(String),
    /// An object's mesh file cannot be used.
    #[error("bad scene: objects[{object}]")]
    Mesh {
        /// Index of the object.
        object: usize,
        /// Why.
        #[source]
        source: crate::mesh::MeshError,
    },
    /// Geometry failed (degenerate board).
    #[error("scene geometry")]
    Geometry(#[source] GeomError),
    /// Frame index past the sweep.
    #[error("frame {index} asked for, the sweep has {frames}")]
    NoSuchFrame {
        /// Asked for.
        index: usize,
        /// Frames in the sweep.
        frames: usize,
    },
}
