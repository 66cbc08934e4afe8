//! A camera path: keyframes of vtkCamera states at times, interpolated smoothly (cubic
//! Hermite with Catmull–Rom tangents over the keyframes' times), for movies. A keyframe is a
//! camera JSON object (the fields of `--camera` files) or ParaView's saved camera state
//! (`.pvcc`, *Save Camera* in ParaView's camera dialog).

use glam::DVec3;
use serde::Deserialize;

use crate::{Camera, CameraError};

/// A camera path's keyframes, in time order.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraPath {
    keys: Vec<(f64, Camera)>,
}

/// Why a camera path cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum CameraPathError {
    /// The path file is not the JSON expected.
    #[error("camera path: {0}")]
    Json(#[from] serde_json::Error),
    /// A keyframe's camera cannot see.
    #[error("camera path keyframe {index}: {source}")]
    Camera {
        /// The keyframe (0-based, in the file's order).
        index: usize,
        /// Why.
        source: CameraError,
    },
    /// Anything else, said in words.
    #[error("camera path: {0}")]
    Other(String),
}

/// One keyframe as written: a time and a camera, inline or in a ParaView `.pvcc` file.
#[derive(Deserialize)]
struct Key {
    time: f64,
    #[serde(default)]
    camera: Option<Camera>,
    #[serde(default)]
    pvcc: Option<String>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum PathFile {
    Keys(Vec<Key>),
    Object { keyframes: Vec<Key> },
}

impl CameraPath {
    /// Parses a path: `{"keyframes": [{"time": t, "camera": {...}} | {"time": t, "pvcc":
    /// "file.pvcc"}, ...]}` (or the list alone); `read` reads a `.pvcc` a keyframe names
    /// (relative to the path file's folder, as the caller resolves it).
    pub fn from_json(
        s: &str,
        read: impl Fn(&str) -> Result<String, String>,
    ) -> Result<CameraPath, CameraPathError> {
        let keys = match serde_json::from_str(s)? {
            PathFile::Keys(k) | PathFile::Object { keyframes: k } => k,
        };
        let mut out = Vec::with_capacity(keys.len());
        for (index, k) in keys.into_iter().enumerate() {
            let cam = match (k.camera, k.pvcc) {
                (Some(c), None) => c,
                (None, Some(f)) => {
                    let text = read(&f).map_err(CameraPathError::Other)?;
                    from_pvcc(&text).map_err(|e| CameraPathError::Other(format!("{f}: {e}")))?
                }
                _ => {
                    return Err(CameraPathError::Other(format!(
                        "keyframe {index}: give either \"camera\" or \"pvcc\""
                    )))
                }
            };
            cam.frame(1, 1)
                .map_err(|source| CameraPathError::Camera { index, source })?;
            if !k.time.is_finite() {
                return Err(CameraPathError::Other(format!(
                    "keyframe {index}: time {} is not finite",
                    k.time
                )));
            }
            out.push((k.time, cam));
        }
        CameraPath::new(out)
    }

    /// A path through `keys` (time, camera); at least one, times distinct.
    pub fn new(mut keys: Vec<(f64, Camera)>) -> Result<CameraPath, CameraPathError> {
        if keys.is_empty() {
            return Err(CameraPathError::Other("no keyframes".into()));
        }
        keys.sort_by(|a, b| a.0.total_cmp(&b.0));
        if keys.windows(2).any(|w| w[0].0 == w[1].0) {
            return Err(CameraPathError::Other("two keyframes at one time".into()));
        }
        Ok(CameraPath { keys })
    }

    /// The first and last keyframes' times.
    pub fn span(&self) -> (f64, f64) {
        let first = self.keys.first().map_or(0.0, |k| k.0);
        (first, self.keys.last().map_or(first, |k| k.0))
    }

    /// The camera at time `t`: the keyframes' exactly at their times, a smooth curve
    /// between them (position, focal point, view up, view angle, parallel scale), the first
    /// or last keyframe's before and after the path.
    pub fn at(&self, t: f64) -> Camera {
        let k = &self.keys;
        let i = k.partition_point(|key| key.0 <= t);
        if i == 0 || i >= k.len() {
            let end = if i == 0 { k.first() } else { k.last() };
            return end.map(|e| e.1.clone()).unwrap_or_default();
        }
        let at = |j: usize| &k[j.min(k.len() - 1)];
        let (p0, p1, p2, p3) = (at(i.saturating_sub(2)), at(i - 1), at(i), at(i + 1));
        let s = (t - p1.0) / (p2.0 - p1.0);
        let v = |f: fn(&Camera) -> DVec3| hermite([p0, p1, p2, p3].map(|p| (p.0, f(&p.1))), s);
        let x = |f: fn(&Camera) -> f64| {
            hermite([p0, p1, p2, p3].map(|p| (p.0, DVec3::splat(f(&p.1)))), s).x
        };
        let mut c = p1.1.clone();
        c.position = v(|c| DVec3::from(c.position)).into();
        c.focal_point = v(|c| DVec3::from(c.focal_point)).into();
        c.view_up = v(|c| DVec3::from(c.view_up)).normalize_or(DVec3::Y).into();
        c.view_angle = x(|c| c.view_angle);
        c.parallel_scale = x(|c| c.parallel_scale);
        c.orthogonalize_view_up();
        c
    }
}

/// Cubic Hermite between the middle two of four (time, value) points at `s` in [0, 1], with
/// Catmull–Rom tangents over the times (an end point repeated gives the chord's slope).
fn hermite(p: [(f64, DVec3); 4], s: f64) -> DVec3 {
    let [(t0, v0), (t1, v1), (t2, v2), (t3, v3)] = p;
    let slope = |(ta, va): (f64, DVec3), (tb, vb): (f64, DVec3)| {
        if tb > ta {
            (vb - va) / (tb - ta)
        } else {
            DVec3::ZERO
        }
    };
    let chord = slope((t1, v1), (t2, v2));
    let m1 = if t0 < t1 {
        slope((t0, v0), (t2, v2))
    } else {
        chord
    };
    let m2 = if t3 > t2 {
        slope((t1, v1), (t3, v3))
    } else {
        chord
    };
    let h = t2 - t1;
    let (s2, s3) = (s * s, s * s * s);
    v1 * (2.0 * s3 - 3.0 * s2 + 1.0)
        + m1 * h * (s3 - 2.0 * s2 + s)
        + v2 * (-2.0 * s3 + 3.0 * s2)
        + m2 * h * (s3 - s2)
}

/// A camera from ParaView's saved camera state (`.pvcc`: `CameraPosition`,
/// `CameraFocalPoint`, `CameraViewUp`, `CameraViewAngle`, `CameraParallelScale`,
/// `CameraParallelProjection` properties with their `Element` values).
pub fn from_pvcc(text: &str) -> Result<Camera, String> {
    let values = |name: &str| -> Result<Vec<f64>, String> {
        let start = text
            .find(&format!("name=\"{name}\""))
            .ok_or_else(|| format!("no property {name}"))?;
        let rest = text.get(start..).unwrap_or_default();
        let end = rest.find("</Property>").unwrap_or(rest.len());
        rest.get(..end)
            .unwrap_or_default()
            .split("<Element")
            .skip(1)
            .map(|e| {
                let v = e.split("value=\"").nth(1).and_then(|v| v.split('"').next());
                v.and_then(|v| v.trim().parse::<f64>().ok())
                    .ok_or_else(|| format!("property {name}: an element without a number"))
            })
            .collect()
    };
    let vec3 = |name: &str| -> Result<[f64; 3], String> {
        match values(name)?.as_slice() {
            [x, y, z] => Ok([*x, *y, *z]),
            v => Err(format!("property {name}: {} values, not 3", v.len())),
        }
    };
    let one = |name: &str, default: f64| -> Result<f64, String> {
        match values(name) {
            Ok(v) => v
                .first()
                .copied()
                .ok_or_else(|| format!("property {name}: no value")),
            Err(_) => Ok(default),
        }
    };
    Ok(Camera {
        position: vec3("CameraPosition")?,
        focal_point: vec3("CameraFocalPoint")?,
        view_up: vec3("CameraViewUp")?,
        view_angle: one("CameraViewAngle", 30.0)?,
        parallel_scale: one("CameraParallelScale", 1.0)?,
        parallel_projection: one("CameraParallelProjection", 0.0)? != 0.0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(x: f64, angle: f64) -> Camera {
        Camera {
            position: [x, 0.0, 10.0],
            focal_point: [x, 0.0, 0.0],
            view_up: [0.0, 1.0, 0.0],
            view_angle: angle,
            ..Default::default()
        }
    }

    #[test]
    fn a_path_passes_through_its_keyframes_and_is_smooth_between() {
        let p = CameraPath::new(vec![
            (0.0, cam(0.0, 30.0)),
            (1.0, cam(1.0, 30.0)),
            (3.0, cam(9.0, 40.0)),
        ])
        .unwrap();
        for (t, want) in [(0.0, 0.0), (1.0, 1.0), (3.0, 9.0)] {
            assert!((p.at(t).position[0] - want).abs() < 1e-12, "t = {t}");
        }
        assert_eq!(p.at(-5.0), cam(0.0, 30.0));
        assert_eq!(p.at(7.0), cam(9.0, 40.0));
        // Between keyframes: within the neighbours' range, and continuous.
        let (a, b) = (p.at(1.0 - 1e-6).position[0], p.at(1.0 + 1e-6).position[0]);
        assert!((a - b).abs() < 1e-4, "{a} {b}");
        let mid = p.at(2.0);
        assert!(mid.position[0] > 1.0 && mid.position[0] < 9.0);
        assert!(mid.view_angle > 30.0 && mid.view_angle < 40.0);
        // Two keyframes: a straight line at constant speed.
        let two = CameraPath::new(vec![(0.0, cam(0.0, 30.0)), (2.0, cam(4.0, 30.0))]).unwrap();
        assert!((two.at(0.5).position[0] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn keyframes_come_from_json_or_paraview_camera_files() {
        let pvcc = r#"<PVCameraConfiguration version="1.0"><Proxy group="views" type="RenderView">
<Property name="CameraPosition" number_of_elements="3"><Element index="0" value="1"/><Element index="1" value="2"/><Element index="2" value="8"/></Property>
<Property name="CameraFocalPoint" number_of_elements="3"><Element index="0" value="1"/><Element index="1" value="2"/><Element index="2" value="0"/></Property>
<Property name="CameraViewUp" number_of_elements="3"><Element index="0" value="0"/><Element index="1" value="1"/><Element index="2" value="0"/></Property>
<Property name="CameraViewAngle" number_of_elements="1"><Element index="0" value="25"/></Property>
</Proxy></PVCameraConfiguration>"#;
        let json = r#"{"keyframes": [{"time": 0, "pvcc": "a.pvcc"},
            {"time": 2, "camera": {"position": [0,0,5], "focal_point": [0,0,0], "view_up": [0,1,0], "view_angle": 30}}]}"#;
        let p = CameraPath::from_json(json, |f| {
            (f == "a.pvcc")
                .then(|| pvcc.to_string())
                .ok_or(format!("{f}: missing"))
        })
        .unwrap();
        let first = p.at(0.0);
        assert_eq!((first.position, first.view_angle), ([1.0, 2.0, 8.0], 25.0));
        assert_eq!(p.span(), (0.0, 2.0));
        let bad = r#"[{"time": 0, "camera": {"position": [0,0,0], "focal_point": [0,0,0], "view_up": [0,1,0]}}]"#;
        let e = CameraPath::from_json(bad, |_| Err("none".into())).unwrap_err();
        assert!(e.to_string().contains("keyframe 0"), "{e}");
        assert!(CameraPath::from_json("[]", |_| Err("none".into())).is_err());
        assert!(from_pvcc("<x/>").unwrap_err().contains("CameraPosition"));
    }
}
