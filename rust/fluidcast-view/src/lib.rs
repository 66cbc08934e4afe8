//! Cameras in vtkCamera terms and transfer functions in ParaView preset terms.

mod camera;
mod presets_data;
mod transfer;

pub use camera::{Camera, CameraError, ViewFrame};
pub use transfer::{TfLookup, TransferFunction, TransferFunctionError};
