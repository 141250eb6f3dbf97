//! OpenCV calibration files (`cv::FileStorage` YAML and XML) in and out.
//!
//! ```text
//! file.yml / file.xml --(storage::parse)--> Storage --(import)--> Head | StereoHead | camera
//!                                                                   --(Imported::into_rig)--> RigCalibration
//! RigCalibration --(export::rig_to_storage)--> Storage --(storage::to_text)--> file.yml / file.xml
//! ```
//!
//! `storage` reads and writes the FileStorage subset (`yaml`, `xml`: one reader each);
//! `import` maps OpenCV's keys and conventions onto our models and checks them
//! (finite, proper rotations, the direction of `R, T`); `export` goes the other way.

mod error;
pub mod export;
pub mod import;
pub mod storage;
mod xml;
mod yaml;

pub use export::{rig_to_storage, write_opencv, ExportError};
pub use import::{
    import_storage, parse_opencv, read_opencv, ImportError, ImportOptions, Imported, LengthUnit,
    SecondDevice,
};
pub use storage::{Format, Matrix, Storage, StorageError, Value};

#[cfg(test)]
mod tests;
