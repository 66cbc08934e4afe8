//! RGBA float images with a depth channel: EXR and PNG output, reading back, comparison.
//!
//! Rows are stored top row first (PNG/EXR order); pixel (i, j) covers [i, i+1) × [j, j+1)
//! with j = 0 the top row. Colours are linear, **premultiplied** by alpha.
#![warn(missing_docs)]

use std::path::{Path, PathBuf};

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Layer, LayerAttributes, SmallVec, WritableImage,
};

/// How 8-bit PNG values are made from the composited colour.
///
/// VTK and ParaView write the composited colour straight into the 8-bit window (a colour
/// map's RGB values are display values), so [`PngEncoding::Vtk`] — the default — gives the
/// same bytes a ParaView screenshot has for the same colour map. [`PngEncoding::Srgb`]
/// treats colours as linear light and applies the sRGB transfer curve (brighter mid-tones).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PngEncoding {
    /// Colour values written as they are, as VTK and ParaView screenshots write them.
    #[default]
    Vtk,
    /// Colours taken as linear light and encoded with the sRGB transfer curve.
    Srgb,
}

/// An image problem, naming the file.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// Reading or writing `file` failed.
    #[error("{file}: {message}")]
    File {
        /// The image file.
        file: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// Two images compared have different sizes (width × height of each).
    #[error("images differ in size: {0}x{1} vs {2}x{3}")]
    SizeMismatch(u32, u32, u32, u32),
    /// A file name whose extension is neither .exr nor .png.
    #[error("unsupported image format for '{0}' (use .exr or .png)")]
    Format(PathBuf),
}

fn ferr(file: &Path, e: impl std::fmt::Display) -> ImageError {
    ImageError::File {
        file: file.to_path_buf(),
        message: e.to_string(),
    }
}

/// A rendered image: premultiplied linear RGBA and, per pixel, the view depth (world units
/// along the camera's forward axis) at which accumulated opacity first exceeded ½, or
/// +∞ where it never did.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Pixels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Premultiplied linear RGBA per pixel, row by row from the top.
    pub rgba: Vec<[f32; 4]>,
    /// View depth per pixel (world units; +∞: opacity never passed ½).
    pub depth: Vec<f32>,
    /// Extra per-pixel channels (arbitrary output values: diagnostics such as a predicted
    /// error bound), written as further EXR channels under their names.
    pub aovs: Vec<(String, Vec<f32>)>,
}

impl Image {
    /// A transparent image with infinite depth.
    pub fn new(width: u32, height: u32) -> Image {
        let n = width as usize * height as usize;
        Image {
            width,
            height,
            rgba: vec![[0.0; 4]; n],
            depth: vec![f32::INFINITY; n],
            aovs: Vec::new(),
        }
    }

    /// Pixel index of (i, j), j = 0 at the top.
    pub fn index(&self, i: u32, j: u32) -> usize {
        j as usize * self.width as usize + i as usize
    }

    /// Writes by extension: `.exr` (float RGBA + Z) or `.png` (8-bit over `background`,
    /// encoded as `png`).
    pub fn save(
        &self,
        path: &Path,
        background: [f32; 3],
        png: PngEncoding,
    ) -> Result<(), ImageError> {
        match ext(path).as_str() {
            "exr" => self.write_exr(path),
            "png" => self.write_png(path, background, png),
            _ => Err(ImageError::Format(path.to_path_buf())),
        }
    }

    /// EXR with channels R, G, B, A (premultiplied, linear), Z (depth) and the AOVs, 32-bit
    /// float.
    pub fn write_exr(&self, path: &Path) -> Result<(), ImageError> {
        let ch = |k: usize| FlatSamples::F32(self.rgba.iter().map(|p| p[k]).collect());
        let mut list = vec![
            AnyChannel::new("R", ch(0)),
            AnyChannel::new("G", ch(1)),
            AnyChannel::new("B", ch(2)),
            AnyChannel::new("A", ch(3)),
            AnyChannel::new("Z", FlatSamples::F32(self.depth.clone())),
        ];
        for (name, v) in &self.aovs {
            list.push(AnyChannel::new(name.as_str(), FlatSamples::F32(v.clone())));
        }
        let channels = AnyChannels::sort(SmallVec::from_vec(list));
        let layer = Layer::new(
            (self.width as usize, self.height as usize),
            LayerAttributes::named("fluidcast"),
            Encoding::FAST_LOSSLESS,
            channels,
        );
        exr::prelude::Image::from_layer(layer)
            .write()
            .to_file(path)
            .map_err(|e| ferr(path, e))
    }

    /// Composites over `background` and writes an 8-bit RGB PNG.
    pub fn write_png(
        &self,
        path: &Path,
        background: [f32; 3],
        encoding: PngEncoding,
    ) -> Result<(), ImageError> {
        let data = self.to_rgb8(background, encoding);
        let f = std::fs::File::create(path).map_err(|e| ferr(path, e))?;
        let mut enc = png::Encoder::new(std::io::BufWriter::new(f), self.width, self.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(|e| ferr(path, e))?;
        w.write_image_data(&data).map_err(|e| ferr(path, e))
    }

    /// 8-bit RGB bytes: the colour composited over `background`, then encoded.
    pub fn to_rgb8(&self, background: [f32; 3], encoding: PngEncoding) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.rgba.len() * 3);
        for p in &self.rgba {
            for k in 0..3 {
                let c = (p[k] + (1.0 - p[3]) * background[k]).clamp(0.0, 1.0);
                let e = match encoding {
                    PngEncoding::Vtk => c,
                    PngEncoding::Srgb => linear_to_srgb(c),
                };
                out.push((e * 255.0).round() as u8);
            }
        }
        out
    }

    /// Reads an EXR written by [`Image::write_exr`] (R, G, B, A, optional Z) or a PNG
    /// (8-bit or 16-bit; values taken as stored, in 0..1, with no transfer curve undone —
    /// the convention of [`PngEncoding::Vtk`]; opaque when it has no alpha).
    pub fn read(path: &Path) -> Result<Image, ImageError> {
        let kind = ext(path);
        if !matches!(kind.as_str(), "exr" | "png") {
            return Err(ImageError::Format(path.to_path_buf()));
        }
        let bytes = fluidcast_mem::read_file(path).map_err(|e| ferr(path, e))?;
        Image::decode(&bytes, path)
    }

    /// Decodes an EXR or PNG from its bytes; `path` names it in errors and its extension
    /// chooses the format. Sizes in the header are checked against what the bytes can hold
    /// and against the memory budget before any pixel buffer is allocated.
    pub fn decode(bytes: &[u8], path: &Path) -> Result<Image, ImageError> {
        match ext(path).as_str() {
            "exr" => decode_exr(bytes, path),
            "png" => decode_png(bytes, path),
            _ => Err(ImageError::Format(path.to_path_buf())),
        }
    }
}

/// The largest expansion of any lossless compression PNG or EXR use (deflate's is 1032:1;
/// EXR's RLE 64:1): a header claiming more pixel bytes than this times the file is lying.
const MAX_COMPRESSION_RATIO: u64 = 1100;

/// Refuses a decoded size the file cannot hold or the machine cannot give.
fn check_claimed_size(
    path: &Path,
    file_len: usize,
    w: u64,
    h: u64,
    decoded: u64,
) -> Result<(), ImageError> {
    let bound = (file_len as u64).saturating_mul(MAX_COMPRESSION_RATIO);
    if decoded > bound {
        return Err(ferr(
            path,
            format!(
                "the header claims {w}x{h} pixels ({decoded} bytes decoded), more than a file of \
                 {file_len} bytes can hold (damaged or forged header)"
            ),
        ));
    }
    // The decoded buffer plus the RGBA f32 image and depth (20 bytes per pixel).
    let total = decoded.saturating_add(w.saturating_mul(h).saturating_mul(20));
    fluidcast_mem::check(|| format!("a {w}x{h} image"), total).map_err(|e| ferr(path, e))
}

fn decode_png(bytes: &[u8], path: &Path) -> Result<Image, ImageError> {
    let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
    dec.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut r = dec.read_info().map_err(|e| ferr(path, e))?;
    let (w, h) = r.info().size();
    check_claimed_size(
        path,
        bytes.len(),
        w.into(),
        h.into(),
        r.output_buffer_size() as u64,
    )?;
    let mut buf = vec![0; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).map_err(|e| ferr(path, e))?;
    let nc = info.color_type.samples();
    let mut out = Image::new(info.width, info.height);
    let data = buf.get(..info.buffer_size()).unwrap_or_default();
    for (p, px) in out.rgba.iter_mut().zip(data.chunks_exact(nc)) {
        let g = |k: usize| f32::from(px.get(k).copied().unwrap_or(0)) / 255.0;
        *p = match nc {
            1 => [g(0), g(0), g(0), 1.0],
            2 => [g(0), g(0), g(0), g(1)],
            3 => [g(0), g(1), g(2), 1.0],
            _ => [g(0), g(1), g(2), g(3)],
        };
    }
    Ok(out)
}

fn decode_exr(bytes: &[u8], path: &Path) -> Result<Image, ImageError> {
    use exr::prelude::ReadChannels as _;
    use exr::prelude::ReadLayers as _;
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .map_err(|e| ferr(path, e))?;
    for h in &meta.headers {
        let (w, hh) = (h.layer_size.0 as u64, h.layer_size.1 as u64);
        let decoded = w
            .saturating_mul(hh)
            .saturating_mul(h.channels.list.len() as u64)
            .saturating_mul(4);
        check_claimed_size(path, bytes.len(), w, hh, decoded)?;
    }
    let img = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| ferr(path, e))?;
    let layer = img
        .layer_data
        .first()
        .ok_or_else(|| ferr(path, "no layers"))?;
    let (w, h) = (layer.size.0, layer.size.1);
    let (Ok(w), Ok(h)) = (u32::try_from(w), u32::try_from(h)) else {
        return Err(ferr(path, format!("image size {w}x{h} is too large")));
    };
    let mut out = Image::new(w, h);
    for c in &layer.channel_data.list {
        let name = c.name.to_string();
        let vals: Vec<f32> = c.sample_data.values_as_f32().collect();
        match "RGBA".find(name.as_str()).filter(|_| name.len() == 1) {
            Some(k) => {
                for (p, v) in out.rgba.iter_mut().zip(vals) {
                    if let Some(slot) = p.get_mut(k) {
                        *slot = v;
                    }
                }
            }
            None if name == "Z" => out.depth = vals,
            None => out.aovs.push((name, vals)),
        }
    }
    Ok(out)
}

fn ext(p: &Path) -> String {
    p.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// sRGB transfer curve (IEC 61966-2-1).
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Differences between two images over the RGBA channels (values in [0, 1]) and the depth
/// channel (view depth in world units, `+∞` where a ray never became half opaque).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Comparison {
    /// Largest absolute channel difference.
    pub max_abs: f64,
    /// Root mean square over all channels of all pixels.
    pub rmse: f64,
    /// Share of pixels (0..1) whose largest channel difference exceeds `tolerance`.
    pub frac_above: f64,
    /// The tolerance used for `frac_above`.
    pub tolerance: f64,
    /// Largest depth difference (world units); `+∞` where one image has a depth and the
    /// other none, 0 where neither has one.
    pub depth_max_abs: f64,
    /// Share of pixels (0..1) whose depths differ at all.
    pub depth_frac_differ: f64,
}

/// |a − b| for two depths, `+∞` when exactly one is infinite, 0 when both are.
fn depth_difference(a: f32, b: f32) -> f64 {
    match (a.is_finite(), b.is_finite()) {
        (true, true) => (a as f64 - b as f64).abs(),
        (false, false) if a == b => 0.0,
        _ => f64::INFINITY,
    }
}

/// Compares two images channel by channel; `diff` (if asked) gets |a − b| per pixel as an
/// opaque image scaled by `1/tolerance` for visibility (clamped).
pub fn compare(a: &Image, b: &Image, tolerance: f64) -> Result<(Comparison, Image), ImageError> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(ImageError::SizeMismatch(
            a.width, a.height, b.width, b.height,
        ));
    }
    let mut max_abs = 0.0f64;
    let mut sq = 0.0f64;
    let mut above = 0usize;
    let mut diff = Image::new(a.width, a.height);
    for (i, (p, q)) in a.rgba.iter().zip(&b.rgba).enumerate() {
        let mut m = 0.0f64;
        for k in 0..4 {
            let d = (p[k] as f64 - q[k] as f64).abs();
            m = m.max(d);
            sq += d * d;
        }
        max_abs = max_abs.max(m);
        above += usize::from(m > tolerance);
        let v = (m / tolerance.max(1e-12)).min(1.0) as f32;
        diff.rgba[i] = [v, v, v, 1.0];
    }
    let n = a.rgba.len().max(1);
    let dz = a
        .depth
        .iter()
        .zip(&b.depth)
        .map(|(&p, &q)| depth_difference(p, q));
    let (depth_max_abs, depth_differ) = dz.fold((0.0f64, 0usize), |(m, k), d| {
        (m.max(d), k + usize::from(d != 0.0))
    });
    Ok((
        Comparison {
            max_abs,
            rmse: (sq / (4 * n) as f64).sqrt(),
            frac_above: above as f64 / n as f64,
            tolerance,
            depth_max_abs,
            depth_frac_differ: depth_differ as f64 / n as f64,
        },
        diff,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trip_and_compare() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let mut a = Image::new(5, 3);
        let k = a.index(4, 2);
        a.rgba[k] = [0.25, 0.5, 0.125, 0.75];
        a.depth[k] = 2.5;
        let p = dir.join("a.exr");
        a.write_exr(&p).unwrap();
        let b = Image::read(&p).unwrap();
        assert_eq!(a, b);
        let mut c = b.clone();
        c.rgba[0][0] = 0.1;
        let (cmp, _) = compare(&a, &c, 0.05).unwrap();
        assert!((cmp.max_abs - 0.1).abs() < 1e-7);
        assert!((cmp.frac_above - 1.0 / 15.0).abs() < 1e-12);
        assert_eq!((cmp.depth_max_abs, cmp.depth_frac_differ), (0.0, 0.0));
        // Depth is compared too: a moved depth, and a depth where the other image has none.
        c.depth[k] = 3.0;
        let (cmp, _) = compare(&a, &c, 0.05).unwrap();
        assert_eq!(cmp.depth_max_abs, 0.5);
        assert!((cmp.depth_frac_differ - 1.0 / 15.0).abs() < 1e-12);
        c.depth[1] = 7.0;
        let (cmp, _) = compare(&c, &a, 0.05).unwrap();
        assert_eq!(cmp.depth_max_abs, f64::INFINITY);
        assert!((cmp.depth_frac_differ - 2.0 / 15.0).abs() < 1e-12);
        let png = dir.join("a.png");
        // Over black, premultiplied 0.5 is stored as 128 (VTK's convention: no curve) and
        // as 188 with the sRGB curve.
        a.write_png(&png, [0.0; 3], PngEncoding::Vtk).unwrap();
        let r = Image::read(&png).unwrap();
        assert_eq!(r.rgba[a.index(4, 2)][1], 128.0 / 255.0);
        a.write_png(&png, [0.0; 3], PngEncoding::Srgb).unwrap();
        let r = Image::read(&png).unwrap();
        assert_eq!(r.rgba[a.index(4, 2)][1], 188.0 / 255.0);
    }
}
