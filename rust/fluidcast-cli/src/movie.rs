//! Camera motion and movies: `--orbit N` turns the camera about its focal point, `-o run.mp4`
//! (`.webm`, `.gif`, `.mkv`, `.mov`) encodes the frames with ffmpeg at `--fps`.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context, Result};
use fluidcast_view::{Camera, CameraPath};

/// Camera motion and movie encoding.
#[derive(clap::Args, Clone, Debug)]
#[command(next_help_heading = "Output, series and movies")]
pub struct MovieArgs {
    /// N views around the focal point (turned about view up, 360/N degrees apart, as
    /// vtkCamera::Azimuth): N images of one file, or, over a series, a turn of 360/N degrees
    /// from each frame to the next.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100000))]
    pub orbit: Option<u32>,
    /// A camera path (JSON): keyframes {"time": T, "camera": {vtkCamera fields}} or
    /// {"time": T, "pvcc": "view.pvcc"} (ParaView's saved camera), interpolated smoothly.
    /// Over a series each frame takes the camera at its time (a .pvd's time step; a
    /// numbered series' index); one file is rendered --path-frames times along the path.
    #[arg(long, conflicts_with = "orbit")]
    pub camera_path: Option<PathBuf>,
    /// Images along a camera path when one file is rendered.
    #[arg(long, default_value = "48", value_parser = clap::value_parser!(u32).range(1..=100000))]
    pub path_frames: u32,
    /// Frames per second of a movie output (-o run.mp4, .webm, .gif, .mkv, .mov).
    #[arg(long, default_value = "24", value_parser = parse_fps)]
    pub fps: f64,
}

/// A frame rate: a finite number of frames per second from 0.01 to 1000.
fn parse_fps(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if (0.01..=1000.0).contains(&v) => Ok(v),
        _ => Err(format!(
            "{s}: frames per second, a number from 0.01 to 1000"
        )),
    }
}

impl MovieArgs {
    /// The camera path `--camera-path` names, its `.pvcc` keyframes read beside it.
    pub fn path(&self) -> Result<Option<CameraPath>> {
        let Some(file) = &self.camera_path else {
            return Ok(None);
        };
        let text = fluidcast_mem::read_text(file)
            .with_context(|| format!("reading camera path {}", file.display()))?;
        let dir = file.parent().unwrap_or(Path::new("."));
        let read = |name: &str| {
            fluidcast_mem::read_text(&dir.join(name)).map_err(|e| format!("{name}: {e}"))
        };
        let path =
            CameraPath::from_json(&text, read).with_context(|| file.display().to_string())?;
        Ok(Some(path))
    }

    /// The cameras of one loaded frame: along `path` (its `--path-frames` views of a single
    /// frame, or the camera at the frame's `time`), else `--orbit`'s turns of `base`.
    pub fn views(
        &self,
        path: Option<&CameraPath>,
        base: &Camera,
        single_frame: bool,
        (position, time): (usize, Option<f64>),
    ) -> Vec<Camera> {
        match path {
            Some(p) if single_frame => {
                let (a, b) = p.span();
                let n = self.path_frames.max(1);
                (0..n)
                    .map(|k| {
                        let s = if n > 1 {
                            f64::from(k) / f64::from(n - 1)
                        } else {
                            0.0
                        };
                        p.at(a + s * (b - a))
                    })
                    .collect()
            }
            Some(p) => vec![p.at(time.unwrap_or(position as f64))],
            None => azimuths(self.orbit, single_frame, position)
                .into_iter()
                .map(|deg| turned(base, deg))
                .collect(),
        }
    }
}

/// The azimuths (degrees) of the views of one loaded frame: N around a single file with
/// `--orbit N`; over a series, the one of the `position`-th image written.
pub fn azimuths(orbit: Option<u32>, single_file: bool, position: usize) -> Vec<f64> {
    match orbit {
        None => vec![0.0],
        Some(n) if single_file => (0..n)
            .map(|k| 360.0 * f64::from(k) / f64::from(n))
            .collect(),
        Some(n) => vec![360.0 * (position % n as usize) as f64 / f64::from(n)],
    }
}

/// `base` turned by `deg` about its view up through the focal point.
pub fn turned(base: &Camera, deg: f64) -> Camera {
    let mut c = base.clone();
    if deg != 0.0 {
        c.azimuth(deg);
        c.orthogonalize_view_up();
    }
    c
}

/// The movie containers ffmpeg writes for `-o`.
const MOVIE_EXTENSIONS: [&str; 5] = ["mp4", "webm", "gif", "mkv", "mov"];

/// A movie being made: its frames go to a folder of PNGs, which ffmpeg encodes at the end
/// and which is removed then (or when the render fails).
pub struct Movie {
    out: PathBuf,
    dir: PathBuf,
}

impl Movie {
    /// A movie when `out` names one (by extension), after checking that ffmpeg is there.
    pub fn for_output(out: &Path) -> Result<Option<Movie>> {
        let ext = out
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        if !ext.is_some_and(|e| MOVIE_EXTENSIONS.contains(&e.as_str())) {
            return Ok(None);
        }
        if out.to_string_lossy().contains('%') {
            bail!("-o {}: a movie is one file, not a pattern", out.display());
        }
        ffmpeg_version().with_context(|| {
            format!(
                "-o {}: writing a movie needs ffmpeg on the PATH (Debian/Ubuntu: apt install \
                 ffmpeg; or write numbered images, -o frame_%04d.png, and encode them yourself)",
                out.display()
            )
        })?;
        let stamp = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        let dir = std::env::temp_dir().join(format!("fluidcast-{}-{stamp}", std::process::id()));
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("making the frames' folder {}", dir.display()))?;
        Ok(Some(Movie {
            out: out.to_path_buf(),
            dir,
        }))
    }

    /// Where the frames are written, numbered from 0.
    pub fn pattern(&self) -> PathBuf {
        self.dir.join("frame_%06d.png")
    }

    /// Encodes the frames written at `fps` frames per second into the movie.
    pub fn encode(&self, fps: f64, frames: usize) -> Result<()> {
        let input = self.pattern();
        let mut cmd = Command::new("ffmpeg");
        cmd.args([
            "-y",
            "-loglevel",
            "error",
            "-framerate",
            &format!("{fps}"),
            "-i",
        ])
        .arg(&input);
        let gif = self
            .out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("gif"));
        if !gif {
            // Even sizes and 4:2:0 chroma: what players take.
            cmd.args([
                "-vf",
                "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                "-pix_fmt",
                "yuv420p",
            ]);
        }
        let status = cmd.arg(&self.out).status().context("running ffmpeg")?;
        if !status.success() {
            bail!("ffmpeg could not write {} ({status})", self.out.display());
        }
        eprintln!(
            "wrote {} ({frames} frames at {fps} frames/s)",
            self.out.display()
        );
        Ok(())
    }
}

impl Drop for Movie {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn ffmpeg_version() -> Result<()> {
    let out = Command::new("ffmpeg").arg("-version").output()?;
    if !out.status.success() {
        bail!("ffmpeg -version failed");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orbits_turn_evenly_around_and_a_series_turns_frame_by_frame() {
        assert_eq!(azimuths(None, true, 5), [0.0]);
        assert_eq!(azimuths(Some(4), true, 0), [0.0, 90.0, 180.0, 270.0]);
        assert_eq!(azimuths(Some(4), false, 6), [180.0]);
        let base = Camera {
            position: [0.0, 0.0, 10.0],
            focal_point: [0.0; 3],
            view_up: [0.0, 1.0, 0.0],
            ..Default::default()
        };
        let c = turned(&base, 90.0);
        assert!((c.position[0] - 10.0).abs() < 1e-9 && c.position[2].abs() < 1e-9);
        assert_eq!(turned(&base, 0.0).position, base.position);
    }
}
