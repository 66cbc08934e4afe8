//! Cameras in vtkCamera terms, transfer functions in ParaView preset terms, and lighting in
//! vtkVolumeProperty's.
#![warn(missing_docs)]

mod camera;
mod camera_path;
mod light;
mod presets_data;
mod transfer;

pub use camera::{Camera, CameraError, ViewFrame};
pub use camera_path::{from_pvcc, CameraPath, CameraPathError};
pub use light::{Light, Lighting, LightingError};
pub use transfer::{TfLookup, TransferFunction, TransferFunctionError};
