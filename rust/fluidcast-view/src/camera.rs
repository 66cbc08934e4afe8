use glam::DVec3;
use serde::{Deserialize, Serialize};

/// A camera with exactly vtkCamera's fields, so a ParaView/pyvista camera carries over.
///
/// World space is the data's own. `view_angle` is vtkCamera's vertical view angle in degrees;
/// with `parallel_projection`, `parallel_scale` is half the view height in world units.
/// JSON keys are snake_case (`focal_point`); VTK's CamelCase names (`FocalPoint`, …) are
/// accepted too.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// The eye (world units).
    #[serde(alias = "Position")]
    pub position: [f64; 3],
    /// The point looked at.
    #[serde(alias = "FocalPoint")]
    pub focal_point: [f64; 3],
    /// The up direction (made orthogonal to the view direction when used).
    #[serde(alias = "ViewUp")]
    pub view_up: [f64; 3],
    /// Vertical view angle, degrees (perspective; default 30).
    #[serde(alias = "ViewAngle", default = "default_angle")]
    pub view_angle: f64,
    /// Parallel instead of perspective projection.
    #[serde(alias = "ParallelProjection", default)]
    pub parallel_projection: bool,
    /// Half the view's height, world units (parallel projection; default 1).
    #[serde(alias = "ParallelScale", default = "one")]
    pub parallel_scale: f64,
}

fn default_angle() -> f64 {
    30.0
}
fn one() -> f64 {
    1.0
}

/// A camera that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// The eye is at the focal point: no view direction.
    #[error("camera position equals the focal point")]
    Degenerate,
    /// The up direction is along the view direction.
    #[error("camera view up is parallel to the view direction")]
    ViewUpParallel,
    /// A view angle outside (0°, 180°).
    #[error("camera view angle {0}° is outside (0°, 180°)")]
    BadAngle(f64),
    /// A parallel scale that is not > 0.
    #[error("camera parallel scale {0} must be > 0")]
    BadScale(f64),
    /// A NaN or infinite value.
    #[error("camera has a non-finite value")]
    NonFinite,
    /// A camera file that is not the JSON expected.
    #[error("camera file: {0}")]
    Json(#[from] serde_json::Error),
}

impl Default for Camera {
    /// vtkCamera's defaults: at (0,0,1) looking at the origin, y up, 30°.
    fn default() -> Self {
        Camera {
            position: [0.0, 0.0, 1.0],
            focal_point: [0.0; 3],
            view_up: [0.0, 1.0, 0.0],
            view_angle: 30.0,
            parallel_projection: false,
            parallel_scale: 1.0,
        }
    }
}

fn rotate(v: DVec3, axis: DVec3, deg: f64) -> DVec3 {
    glam::DQuat::from_axis_angle(axis.normalize(), deg.to_radians()) * v
}

impl Camera {
    /// Parses a camera JSON document.
    pub fn from_json(s: &str) -> Result<Camera, CameraError> {
        let c: Camera = serde_json::from_str(s)?;
        c.frame(1, 1)?;
        Ok(c)
    }

    /// `vtkRenderer::ResetCamera(bounds)`: keeps this camera's view direction and view up,
    /// puts the focal point at the bounds' centre and backs off so that the bounding sphere
    /// (radius = half the diagonal) fills the view angle: `distance = radius / sin(angle/2)`.
    /// `parallel_scale` becomes the radius.
    pub fn reset(&mut self, lo: [f64; 3], hi: [f64; 3]) {
        let lo = DVec3::from(lo);
        let hi = DVec3::from(hi);
        let center = (lo + hi) * 0.5;
        let mut radius = (hi - lo).length() * 0.5;
        if radius == 0.0 || !radius.is_finite() {
            radius = 1.0;
        }
        let mut vn = DVec3::from(self.position) - DVec3::from(self.focal_point);
        if vn.length_squared() == 0.0 {
            vn = DVec3::Z;
        }
        let vn = vn.normalize();
        let mut up = DVec3::from(self.view_up);
        if up.cross(vn).length_squared() < 1e-12 {
            up = if vn.y.abs() < 0.9 {
                DVec3::Y
            } else {
                -DVec3::Z
            };
        }
        let angle = self.view_angle.to_radians();
        let distance = radius / (angle * 0.5).sin();
        self.focal_point = center.to_array();
        self.position = (center + vn * distance).to_array();
        self.view_up = up.to_array();
        self.parallel_scale = radius;
    }

    /// vtkCamera::Azimuth: rotates the position about the view-up vector through the focal
    /// point (degrees, counter-clockwise seen from the tip of view up).
    pub fn azimuth(&mut self, deg: f64) {
        let fp = DVec3::from(self.focal_point);
        let p = DVec3::from(self.position) - fp;
        self.position = (fp + rotate(p, DVec3::from(self.view_up), deg)).to_array();
    }

    /// vtkCamera::Elevation: rotates the position about the axis `focal − position` ×
    /// view up… (the negated right vector) through the focal point; positive moves the camera
    /// up. Like vtkCamera, the view up is left as it is.
    pub fn elevation(&mut self, deg: f64) {
        let fp = DVec3::from(self.focal_point);
        let p = DVec3::from(self.position) - fp;
        let fwd = -p.normalize();
        let right = fwd.cross(DVec3::from(self.view_up)).normalize();
        self.position = (fp + rotate(p, -right, deg)).to_array();
    }

    /// vtkCamera::OrthogonalizeViewUp: makes view up perpendicular to the view direction.
    pub fn orthogonalize_view_up(&mut self) {
        if let Ok(f) = self.frame(1, 1) {
            self.view_up = f.up.to_array();
        }
    }

    /// vtkCamera::Zoom: divides the view angle (perspective) or parallel scale by `factor`.
    pub fn zoom(&mut self, factor: f64) {
        if factor > 0.0 {
            if self.parallel_projection {
                self.parallel_scale /= factor;
            } else {
                self.view_angle /= factor;
            }
        }
    }

    /// The orthonormal view frame for a `width × height` image.
    pub fn frame(&self, width: u32, height: u32) -> Result<ViewFrame, CameraError> {
        let all = self
            .position
            .iter()
            .chain(&self.focal_point)
            .chain(&self.view_up);
        if !all.clone().all(|v| v.is_finite())
            || !self.view_angle.is_finite()
            || !self.parallel_scale.is_finite()
        {
            return Err(CameraError::NonFinite);
        }
        let eye = DVec3::from(self.position);
        let d = DVec3::from(self.focal_point) - eye;
        if d.length_squared() == 0.0 {
            return Err(CameraError::Degenerate);
        }
        let forward = d.normalize();
        let right = forward.cross(DVec3::from(self.view_up));
        if right.length_squared() < 1e-20 {
            return Err(CameraError::ViewUpParallel);
        }
        let right = right.normalize();
        let up = right.cross(forward);
        if self.parallel_projection {
            if self.parallel_scale <= 0.0 {
                return Err(CameraError::BadScale(self.parallel_scale));
            }
        } else if !(self.view_angle > 0.0 && self.view_angle < 180.0) {
            return Err(CameraError::BadAngle(self.view_angle));
        }
        Ok(ViewFrame {
            eye,
            forward,
            right,
            up,
            width,
            height,
            aspect: width as f64 / height as f64,
            tan_half: (self.view_angle.to_radians() * 0.5).tan(),
            parallel: self.parallel_projection.then_some(self.parallel_scale),
        })
    }
}

/// A camera resolved for one image: orthonormal axes and pixel geometry.
///
/// Image convention: pixel (i, j) has its centre at (i + ½, j + ½) with **row j = 0 at the
/// top** (the order PNG and EXR store rows; VTK's own origin is bottom-left, so VTK row
/// `H−1−j` is our row j). View space: x = right, y = up, z = depth along `forward`
/// (positive in front of the camera; this is vtkCamera's view space with z negated).
#[derive(Debug, Clone, Copy)]
pub struct ViewFrame {
    /// The eye (world units).
    pub eye: DVec3,
    /// Unit view direction (world space).
    pub forward: DVec3,
    /// Unit right direction (world space).
    pub right: DVec3,
    /// Unit up direction (world space).
    pub up: DVec3,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// width / height.
    pub aspect: f64,
    /// tan(view_angle / 2).
    pub tan_half: f64,
    /// `Some(parallel_scale)` for a parallel projection.
    pub parallel: Option<f64>,
}

impl ViewFrame {
    /// Normalised device coordinates of a pixel centre, x right, y up, in [-1, 1].
    pub fn ndc(&self, i: f64, j: f64) -> (f64, f64) {
        (
            2.0 * (i + 0.5) / self.width as f64 - 1.0,
            1.0 - 2.0 * (j + 0.5) / self.height as f64,
        )
    }

    /// The ray through pixel centre (i, j): origin and direction with `dir · forward = 1`, so
    /// that the point at view depth z is `origin + z · dir`.
    pub fn ray(&self, i: u32, j: u32) -> (DVec3, DVec3) {
        self.ray_at(i as f64 + 0.5, j as f64 + 0.5)
    }

    /// The ray through continuous pixel coordinates (x, y) (x from the left edge, y from the
    /// top edge; pixel (i, j)'s centre is (i + ½, j + ½)), as [`ViewFrame::ray`].
    pub fn ray_at(&self, x: f64, y: f64) -> (DVec3, DVec3) {
        let (x, y) = self.ndc(x - 0.5, y - 0.5);
        match self.parallel {
            Some(s) => (
                self.eye + self.right * (x * s * self.aspect) + self.up * (y * s),
                self.forward,
            ),
            None => (
                self.eye,
                self.forward
                    + self.right * (x * self.tan_half * self.aspect)
                    + self.up * (y * self.tan_half),
            ),
        }
    }

    /// World point → view space (x right, y up, z depth).
    pub fn to_view(&self, p: DVec3) -> DVec3 {
        let d = p - self.eye;
        DVec3::new(d.dot(self.right), d.dot(self.up), d.dot(self.forward))
    }

    /// A view-space direction (x right, y up, z depth) in world space: the inverse of
    /// [`ViewFrame::to_view`]'s rotation (directions have no origin).
    pub fn direction_to_world(&self, v: [f64; 3]) -> [f64; 3] {
        (self.right * v[0] + self.up * v[1] + self.forward * v[2]).to_array()
    }

    /// World point → continuous pixel coordinates (x from the left edge, y from the top edge;
    /// the centre of pixel (i, j) is (i + ½, j + ½)); `None` behind the camera.
    pub fn project(&self, p: DVec3) -> Option<(f64, f64)> {
        self.project_view(self.to_view(p))
    }

    /// [`ViewFrame::project`] of a point already in view space (see [`ViewFrame::to_view`]).
    pub fn project_view(&self, v: DVec3) -> Option<(f64, f64)> {
        let (x, y) = match self.parallel {
            Some(s) => (v.x / (s * self.aspect), v.y / s),
            None => {
                if v.z <= 0.0 {
                    return None;
                }
                (
                    v.x / (v.z * self.tan_half * self.aspect),
                    v.y / (v.z * self.tan_half),
                )
            }
        };
        Some((
            (x + 1.0) * 0.5 * self.width as f64,
            (1.0 - y) * 0.5 * self.height as f64,
        ))
    }

    /// World size of one pixel at view depth z (the lateral pixel footprint).
    pub fn pixel_size_at(&self, z: f64) -> f64 {
        match self.parallel {
            Some(s) => 2.0 * s / self.height as f64,
            None => 2.0 * z * self.tan_half / self.height as f64,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reset_frames_bounds_like_vtk() {
        let mut c = Camera::default();
        c.reset([-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]);
        let r = 3f64.sqrt();
        let d = r / (15f64.to_radians()).sin();
        assert!((c.position[2] - d).abs() < 1e-12);
        assert_eq!(c.focal_point, [0.0; 3]);
    }

    #[test]
    fn projection_inverts_rays() {
        let mut c = Camera::default();
        c.reset([0.0; 3], [1.0, 2.0, 0.5]);
        c.azimuth(30.0);
        c.elevation(20.0);
        for parallel in [false, true] {
            c.parallel_projection = parallel;
            let f = c.frame(64, 48).unwrap();
            let (o, d) = f.ray(10, 40);
            let (x, y) = f.project(o + d * 3.7).unwrap();
            assert!(
                (x - 10.5).abs() < 1e-9 && (y - 40.5).abs() < 1e-9,
                "{x} {y}"
            );
        }
    }

    #[test]
    fn azimuth_rotates_about_view_up() {
        let mut c = Camera::default();
        c.azimuth(90.0);
        // Counter-clockwise about +y seen from above: +z moves to +x.
        assert!((c.position[0] - 1.0).abs() < 1e-12 && c.position[2].abs() < 1e-12);
        let mut e = Camera::default();
        e.elevation(90.0);
        assert!((e.position[1] - 1.0).abs() < 1e-12);
    }
}
