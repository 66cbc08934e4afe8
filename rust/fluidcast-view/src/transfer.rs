use serde_json::Value;

use crate::presets_data::{
    BLUE_TO_RED_RAINBOW, CIVIDIS, HOT, INFERNO, JET, MAGMA, PLASMA, RAINBOW, RDBU, SEISMIC,
    SPECTRAL, TURBO, TWILIGHT, VIRIDIS,
};

/// A colour + opacity transfer function, as ParaView's colour-map editor defines one.
///
/// Colour control points come from a preset's `RGBPoints` (x, r, g, b, …) and opacity from
/// `Points` (x, opacity, midpoint, sharpness, …); both are rescaled from the preset's own x
/// range to the active data range `[lo, hi]`, as ParaView does when it applies a preset.
/// Values outside the range are clamped; NaN is transparent. Interpolation is linear in RGB
/// (ParaView's `Diverging`/`Lab` colour spaces are approximated in RGB; opacity midpoint and
/// sharpness other than 0.5/0 are ignored).
///
/// Opacity is given for a path of length `unit_distance` (ParaView's "Scalar Opacity Unit
/// Distance", world units) and corrected per step: `α(Δs) = 1 − (1 − α)^(Δs / unit)`.
#[derive(Debug, Clone, PartialEq)]
pub struct TransferFunction {
    /// The preset's or file's name.
    pub name: String,
    /// (x in [0,1], rgb) sorted by x.
    pub colors: Vec<(f64, [f64; 3])>,
    /// (x in [0,1], opacity per unit distance) sorted by x.
    pub opacity: Vec<(f64, f64)>,
    /// Active data range mapped onto x = 0..1.
    pub range: (f64, f64),
    /// Length over which the opacity applies (world units).
    pub unit_distance: f64,
}

/// A transfer function that cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum TransferFunctionError {
    /// A preset name that is neither built in nor a file (the name, the built-in ones).
    #[error(
        "unknown transfer function preset '{0}' (built in: {1}, any of them reversed with _r; \
         or give a ParaView preset .json file: ParaView's other presets, such as Rainbow \
         Uniform or Black-Body Radiation, are exported from its Choose Preset dialog)"
    )]
    UnknownPreset(String, String),
    /// A preset file that cannot be used.
    #[error("{file}: {problem}")]
    File {
        /// The file.
        file: String,
        /// What is wrong with it.
        problem: String,
    },
    /// A range that is not finite lo < hi.
    #[error("bad range {0},{1}: need finite lo < hi")]
    BadRange(f64, f64),
}

const BUILTIN: [&str; 17] = [
    "Cool to Warm",
    "Viridis",
    "Inferno",
    "Grayscale",
    "Plasma",
    "Magma",
    "Cividis",
    "Turbo",
    "Jet",
    "X Ray",
    "Blue to Red Rainbow",
    "Hot",
    "Rainbow",
    "Twilight",
    "RdBu",
    "Spectral",
    "Seismic",
];

fn table(flat: &[f64]) -> Vec<(f64, [f64; 3])> {
    flat.chunks_exact(4)
        .map(|c| (c[0], [c[1], c[2], c[3]]))
        .collect()
}

fn normalise<T: Copy>(pts: &mut [(f64, T)]) {
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (a, b) = (pts[0].0, pts[pts.len() - 1].0);
    for p in pts.iter_mut() {
        p.0 = if b > a { (p.0 - a) / (b - a) } else { 0.0 };
    }
}

/// Where map position `t` falls in the node table `pts`: `Ok(i)` on the segment from node
/// `i − 1` to node `i` (the first node at or right of `t` closes it: a binary search, VTK's and
/// ParaView's tables have 1024 nodes), `Err(value)` left of the first node or right of the last
/// (or at NaN), with the value held there.
fn segment<T: Copy>(pts: &[(f64, T)], t: f64) -> Result<usize, T> {
    if t <= pts[0].0 {
        return Err(pts[0].1);
    }
    match pts.partition_point(|p| p.0 < t) {
        // Right of the last node (or t NaN, which no node is left of).
        i if i == pts.len() || i == 0 => Err(pts[pts.len() - 1].1),
        i => Ok(i),
    }
}

/// The piecewise-linear value of the node table `pts` at map position `t` ([`segment`]).
fn lerp_at<T: Copy>(pts: &[(f64, T)], t: f64, mix: impl Fn(T, T, f64) -> T) -> T {
    let i = match segment(pts, t) {
        Ok(i) => i,
        Err(v) => return v,
    };
    let (a, b) = (pts[i - 1], pts[i]);
    let d = b.0 - a.0;
    let f = if d > 0.0 { (t - a.0) / d } else { 1.0 };
    mix(a.1, b.1, f)
}

/// The colour table of the built-in preset `key` (lower case, spaces), if it is one.
fn preset_colours(key: &str) -> Option<Vec<(f64, [f64; 3])>> {
    let flat: &[f64] = match key {
        "cool to warm" | "coolwarm" => &[
            0.0, 0.231373, 0.298039, 0.752941, 0.5, 0.865003, 0.865003, 0.865003, 1.0, 0.705882,
            0.0156863, 0.14902,
        ],
        "viridis" => &VIRIDIS,
        "inferno" => &INFERNO,
        "grayscale" | "greyscale" | "gray" | "grey" => &[0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
        "plasma" => &PLASMA,
        "magma" => &MAGMA,
        "cividis" => &CIVIDIS,
        "turbo" => &TURBO,
        "jet" => &JET,
        "x ray" | "xray" => &[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0],
        "blue to red rainbow" => &BLUE_TO_RED_RAINBOW,
        "hot" => &HOT,
        "rainbow" => &RAINBOW,
        "twilight" => &TWILIGHT,
        "rdbu" => &RDBU,
        "spectral" => &SPECTRAL,
        "seismic" => &SEISMIC,
        _ => return None,
    };
    Some(table(flat))
}

impl TransferFunction {
    /// A built-in preset (case-insensitive; `-`/`_` match spaces; ParaView's names such as
    /// "Viridis (matplotlib)" and matplotlib's such as "viridis" or "RdBu_r", `_r` reversing
    /// it) with ParaView's default linear opacity ramp 0 → 1.
    pub fn preset(name: &str) -> Result<TransferFunction, TransferFunctionError> {
        let key = name.trim().to_ascii_lowercase().replace(['-', '_'], " ");
        let key = key.strip_suffix(" (matplotlib)").unwrap_or(&key);
        let (key, reversed) = match key.strip_suffix(" r") {
            Some(k) if preset_colours(k).is_some() => (k, true),
            _ => (key, false),
        };
        let Some(mut colors) = preset_colours(key) else {
            return Err(TransferFunctionError::UnknownPreset(
                name.into(),
                BUILTIN.join(", "),
            ));
        };
        if reversed {
            colors = colors
                .into_iter()
                .rev()
                .map(|(x, c)| (1.0 - x, c))
                .collect();
        }
        let canonical = BUILTIN
            .iter()
            .find(|b| b.to_ascii_lowercase() == key)
            .map_or_else(|| name.to_string(), |b| b.to_string());
        Ok(TransferFunction {
            name: if reversed {
                format!("{canonical}_r")
            } else {
                canonical
            },
            colors,
            opacity: vec![(0.0, 0.0), (1.0, 1.0)],
            range: (0.0, 1.0),
            unit_distance: 1.0,
        })
    }

    /// Names of the built-in presets.
    pub fn builtin_names() -> &'static [&'static str] {
        &BUILTIN
    }

    /// Parses ParaView colour-map preset JSON (a list of presets — the first with
    /// `RGBPoints` is used — or one preset object). `file` names the source in errors.
    pub fn from_paraview_json(
        text: &str,
        file: &str,
    ) -> Result<TransferFunction, TransferFunctionError> {
        let err = |p: String| TransferFunctionError::File {
            file: file.into(),
            problem: p,
        };
        let v: Value = serde_json::from_str(text).map_err(|e| err(format!("invalid JSON: {e}")))?;
        let obj = match &v {
            Value::Array(a) => a.iter().find(|p| p.get("RGBPoints").is_some()).cloned(),
            Value::Object(_) => Some(v.clone()),
            _ => None,
        }
        .ok_or_else(|| err("no preset with 'RGBPoints' found".into()))?;
        let nums = |key: &str| -> Result<Option<Vec<f64>>, TransferFunctionError> {
            match obj.get(key) {
                None => Ok(None),
                Some(Value::Array(a)) => a
                    .iter()
                    .map(|x| {
                        x.as_f64()
                            .ok_or_else(|| err(format!("'{key}' holds a non-number")))
                    })
                    .collect::<Result<Vec<_>, _>>()
                    .map(Some),
                Some(_) => Err(err(format!("'{key}' is not an array"))),
            }
        };
        let rgb = nums("RGBPoints")?.ok_or_else(|| err("no 'RGBPoints'".into()))?;
        if rgb.len() < 4 || rgb.len() % 4 != 0 {
            return Err(err(format!(
                "'RGBPoints' needs groups of 4 numbers (x, r, g, b), found {}",
                rgb.len()
            )));
        }
        let mut colors = table(&rgb);
        normalise(&mut colors);
        let mut opacity = match nums("Points")? {
            Some(p) if p.len() >= 4 && p.len() % 4 == 0 => p.chunks_exact(4).map(|c| (c[0], c[1].clamp(0.0, 1.0))).collect(),
            Some(p) if p.len() >= 2 && p.len() % 2 == 0 && p.len() % 4 != 0 => p.chunks_exact(2).map(|c| (c[0], c[1].clamp(0.0, 1.0))).collect(),
            Some(p) => return Err(err(format!("'Points' (opacity) needs groups of 4 numbers (x, opacity, midpoint, sharpness), found {}", p.len()))),
            None => vec![(0.0, 0.0), (1.0, 1.0)],
        };
        normalise(&mut opacity);
        let name = obj
            .get("Name")
            .and_then(Value::as_str)
            .unwrap_or(file)
            .to_string();
        Ok(TransferFunction {
            name,
            colors,
            opacity,
            range: (0.0, 1.0),
            unit_distance: 1.0,
        })
    }

    /// Sets the data range mapped onto the colour map.
    pub fn with_range(mut self, lo: f64, hi: f64) -> Result<Self, TransferFunctionError> {
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(TransferFunctionError::BadRange(lo, hi));
        }
        self.range = (lo, hi);
        Ok(self)
    }

    /// Multiplies all opacities by `s` (clamped to 1).
    pub fn scale_opacity(&mut self, s: f64) {
        for p in &mut self.opacity {
            p.1 = (p.1 * s).clamp(0.0, 1.0);
        }
    }

    /// Position of `q` on the map (0..1, clamped); `None` for NaN.
    #[inline]
    pub fn normalised(&self, q: f64) -> Option<f64> {
        if q.is_nan() {
            return None;
        }
        Some(((q - self.range.0) / (self.range.1 - self.range.0)).clamp(0.0, 1.0))
    }

    /// Colour (linear RGB in [0,1]) and opacity per `unit_distance` at data value `q`.
    pub fn eval(&self, q: f64) -> ([f64; 3], f64) {
        match self.normalised(q) {
            None => ([0.0; 3], 0.0),
            Some(t) => self.eval_normalised(t),
        }
    }

    /// Colour and opacity at map position `t` (0..1, see [`TransferFunction::normalised`]).
    pub fn eval_normalised(&self, t: f64) -> ([f64; 3], f64) {
        (
            lerp_at(&self.colors, t, mix_rgb),
            lerp_at(&self.opacity, t, mix_scalar),
        )
    }

    /// Extinction coefficient κ = −ln(1 − α)/unit (per world unit; +∞ for α ≥ 1), so that
    /// a step of length `ds` has opacity `1 − exp(−κ·ds)` = [`TransferFunction::step_alpha`].
    #[inline]
    pub fn extinction(&self, alpha: f64) -> f64 {
        if alpha >= 1.0 {
            f64::INFINITY
        } else {
            -(1.0 - alpha).ln() / self.unit_distance
        }
    }

    /// Opacity for a step of length `ds` (world units): `1 − (1 − α)^(ds / unit)`, as
    /// `2^(ds/unit · log2(1 − α))` (the power is the ray casters' most frequent call; this form
    /// costs about 60 % of `powf` and agrees with it to a few ulps).
    #[inline]
    pub fn step_alpha(&self, alpha: f64, ds: f64) -> f64 {
        if alpha >= 1.0 {
            return 1.0;
        }
        if alpha <= 0.0 {
            return 0.0;
        }
        1.0 - (ds / self.unit_distance * (1.0 - alpha).log2()).exp2()
    }
}

/// Equal parts of [0, 1] that [`TfLookup`] indexes.
const BUCKETS: usize = 4096;

/// One node table's linear piece over a [`TfLookup`] interval: `a + delta·f` with `f = (t −
/// org)·inv_d` (at most 1), the segment of [`lerp_at`] from node `a` (at `org`) to the next
/// (`delta` = its value − `a`, `inv_d` = 1/its distance); `delta` 0 and `inv_d` 0 left of the
/// first node and right of the last.
#[derive(Debug, Clone, Copy)]
struct Piece<T> {
    org: f64,
    inv_d: f64,
    a: T,
    delta: T,
}

impl<T: Copy> Piece<T> {
    /// The piece of `pts` that holds map position `t` ([`segment`], as [`lerp_at`] takes it).
    fn of(pts: &[(f64, T)], t: f64, sub: impl Fn(T, T) -> T) -> Piece<T> {
        match segment(pts, t) {
            Err(v) => Piece {
                org: 0.0,
                inv_d: 0.0,
                a: v,
                delta: sub(v, v),
            },
            Ok(i) => {
                let (a, b) = (pts[i - 1], pts[i]);
                Piece {
                    org: a.0,
                    inv_d: 1.0 / (b.0 - a.0),
                    a: a.1,
                    delta: sub(b.1, a.1),
                }
            }
        }
    }

    /// The piece's share of the way to its next node at `t`.
    #[inline(always)]
    fn f(&self, t: f64) -> f64 {
        ((t - self.org) * self.inv_d).min(1.0)
    }
}

/// A transfer function indexed for many lookups: both node tables cut at every node of
/// either into intervals `(upper[k − 1], upper[k]]`, on each of which colour and opacity are
/// one linear piece, found through [`BUCKETS`] equal parts of [0, 1]. [`TfLookup::eval`]
/// equals [`TransferFunction::eval`] to a few units in the last place (a product by the
/// segment's reciprocal length in place of a quotient; tested to 1e-12), with one short
/// search in place of a binary search over each table (ParaView's colour maps have up to 1024
/// nodes) and one division in place of three: the colour and opacity of every sample cast.
/// Built once per render.
#[derive(Debug, Clone)]
pub struct TfLookup<'a> {
    /// The transfer function looked up.
    pub tf: &'a TransferFunction,
    /// The intervals' upper ends, ascending; the last is +∞.
    upper: Vec<f64>,
    colour: Vec<Piece<[f64; 3]>>,
    opacity: Vec<Piece<f64>>,
    /// Per part `b` of [`BUCKETS`] (and one beyond), the first interval whose upper end is at
    /// or right of `b / BUCKETS`.
    starts: Vec<u32>,
}

impl<'a> TfLookup<'a> {
    /// The lookup tables of `tf`.
    pub fn new(tf: &'a TransferFunction) -> TfLookup<'a> {
        let mut upper: Vec<f64> = tf
            .colors
            .iter()
            .map(|p| p.0)
            .chain(tf.opacity.iter().map(|p| p.0))
            .filter(|x| !x.is_nan())
            .collect();
        upper.sort_by(f64::total_cmp);
        upper.dedup();
        upper.push(f64::INFINITY);
        let sub3 = |a: [f64; 3], b: [f64; 3]| [0, 1, 2].map(|k| a[k] - b[k]);
        let colour = upper
            .iter()
            .map(|&u| Piece::of(&tf.colors, u, sub3))
            .collect();
        let opacity = upper
            .iter()
            .map(|&u| Piece::of(&tf.opacity, u, |a, b| a - b))
            .collect();
        let starts = (0..=BUCKETS)
            .map(|b| upper.partition_point(|&u| u < b as f64 / BUCKETS as f64) as u32)
            .chain([upper.len() as u32 - 1])
            .collect();
        TfLookup {
            tf,
            upper,
            colour,
            opacity,
            starts,
        }
    }

    /// Colour and opacity per unit distance at data value `q`, as [`TransferFunction::eval`].
    /// (Always inlined: a call per sample returned its tuple through memory, and the ray
    /// casters' loops over samples spent 12 % of a render of a spray in the call.)
    #[inline(always)]
    pub fn eval(&self, q: f64) -> ([f64; 3], f64) {
        // The map position as TransferFunction::normalised divides it: at a step of the
        // map (two nodes at one position) an ulp of t is the step.
        let Some(t) = self.tf.normalised(q) else {
            return ([0.0; 3], 0.0);
        };
        let k = self.interval(t);
        let (c, o) = (&self.colour[k], &self.opacity[k]);
        let f = c.f(t);
        (
            [0, 1, 2].map(|i| c.a[i] + c.delta[i] * f),
            o.a + o.delta * o.f(t),
        )
    }

    /// The interval that holds map position `t` (in [0, 1]): the first whose upper end is at
    /// or right of `t`, searched among those that end in `t`'s part of [0, 1].
    #[inline(always)]
    fn interval(&self, t: f64) -> usize {
        let b = ((t * BUCKETS as f64) as usize).min(BUCKETS);
        let (lo, hi) = (self.starts[b] as usize, self.starts[b + 1] as usize);
        lo + self.upper[lo..=hi].partition_point(|&u| u < t)
    }
}

fn mix_rgb(a: [f64; 3], b: [f64; 3], f: f64) -> [f64; 3] {
    [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * f)
}

fn mix_scalar(a: f64, b: f64, f: f64) -> f64 {
    a + (b - a) * f
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        /// The indexed lookup equals the plain one to 1e-12: random node tables with
        /// repeated nodes and nodes on bucket edges, at random values, at the nodes, on
        /// bucket edges, outside the range and at NaN.
        #[test]
        fn lookup_equals_eval(
            xs in prop::collection::vec(prop_oneof![0.0f64..1.0, (0u32..=16).prop_map(|k| k as f64 / 16.0)], 1..300),
            qs in prop::collection::vec(-0.2f64..1.2, 50),
            lo in -5.0f64..5.0,
            span in 0.01f64..10.0,
        ) {
            let mut xs = xs;
            xs.sort_by(f64::total_cmp);
            let nodes = |k: usize| xs.iter().enumerate().map(|(i, &x)| (x, (i * k % 7) as f64 / 7.0)).collect::<Vec<_>>();
            let tf = TransferFunction {
                name: "random".into(),
                colors: nodes(3).into_iter().map(|(x, v)| (x, [v, 1.0 - v, v * v])).collect(),
                opacity: nodes(5),
                range: (lo, lo + span),
                unit_distance: 1.0,
            };
            let lookup = TfLookup::new(&tf);
            let at = |t: f64| lo + t * span;
            let edges = (0..=BUCKETS).step_by(37).map(|b| at(b as f64 / BUCKETS as f64));
            let all = qs.iter().map(|&t| at(t)).chain(xs.iter().map(|&x| at(x))).chain(edges)
                .chain([f64::NAN, lo, lo + span, f64::INFINITY, f64::NEG_INFINITY]);
            for q in all {
                let (a, b) = (lookup.eval(q), tf.eval(q));
                let off = (0..3).map(|k| (a.0[k] - b.0[k]).abs()).fold((a.1 - b.1).abs(), f64::max);
                prop_assert!(off <= 1e-12, "q {}: {:?} vs {:?}", q, a, b);
            }
        }
    }

    /// The segment search of `lerp_at` against a plain scan of every segment: the same value
    /// everywhere, on tables with repeated nodes (steps) and at the nodes themselves.
    #[test]
    fn lerp_at_matches_a_linear_scan() {
        fn scan(pts: &[(f64, f64)], t: f64) -> f64 {
            if t <= pts[0].0 {
                return pts[0].1;
            }
            for w in pts.windows(2) {
                if t <= w[1].0 {
                    let d = w[1].0 - w[0].0;
                    let f = if d > 0.0 { (t - w[0].0) / d } else { 1.0 };
                    return w[0].1 + (w[1].1 - w[0].1) * f;
                }
            }
            pts[pts.len() - 1].1
        }
        let xs = [0.0, 0.1, 0.1, 0.25, 0.5, 0.5, 0.5, 0.9, 1.0];
        let pts: Vec<(f64, f64)> = xs
            .iter()
            .enumerate()
            .map(|(i, &x)| (x, (i * i) as f64))
            .collect();
        for k in -10..=110 {
            let t = k as f64 / 100.0;
            let got = lerp_at(&pts, t, |a, b, f| a + (b - a) * f);
            assert_eq!(got, scan(&pts, t), "t = {t}");
        }
        for &t in &xs {
            assert_eq!(lerp_at(&pts, t, |a, b, f| a + (b - a) * f), scan(&pts, t));
        }
    }

    #[test]
    fn presets_and_interpolation() {
        for n in TransferFunction::builtin_names() {
            let tf = TransferFunction::preset(n)
                .unwrap()
                .with_range(10.0, 20.0)
                .unwrap();
            assert_eq!(tf.eval(5.0).1, 0.0);
            assert_eq!(tf.eval(25.0).1, 1.0);
            assert!((tf.eval(15.0).1 - 0.5).abs() < 1e-12);
        }
        let g = TransferFunction::preset("grayscale")
            .unwrap()
            .with_range(0.0, 2.0)
            .unwrap();
        assert!((g.eval(0.5).0[1] - 0.25).abs() < 1e-12);
        assert!(TransferFunction::preset("nope").is_err());
    }

    /// The names users type elsewhere: ParaView's ("Viridis (matplotlib)", "Blue to Red
    /// Rainbow") and matplotlib's ("viridis", "RdBu_r" reversed), in any case.
    #[test]
    fn preset_names_from_paraview_and_matplotlib() {
        let colour = |name: &str, x: f64| TransferFunction::preset(name).unwrap().eval(x).0;
        assert_eq!(colour("Viridis (matplotlib)", 0.3), colour("viridis", 0.3));
        assert_eq!(colour("PLASMA", 0.7), colour("Plasma", 0.7));
        assert_eq!(TransferFunction::preset("rdbu").unwrap().name, "RdBu");
        // _r reverses: the colour at x is the original's at 1 - x.
        let r = TransferFunction::preset("RdBu_r").unwrap();
        assert_eq!(r.name, "RdBu_r");
        for x in [0.0, 0.2, 0.55, 1.0] {
            let (a, b) = (r.eval(x).0, colour("RdBu", 1.0 - x));
            assert!(
                (0..3).all(|k| (a[k] - b[k]).abs() < 1e-12),
                "{x}: {a:?} {b:?}"
            );
        }
        // ParaView's Blue to Red Rainbow: the hue sweep, blue at 0, green at 1/2, red at 1.
        for (x, want) in [
            (0.0, [0.0, 0.0, 1.0]),
            (0.5, [0.0, 1.0, 0.0]),
            (1.0, [1.0, 0.0, 0.0]),
        ] {
            let c = colour("blue to red rainbow", x);
            assert!((0..3).all(|k| (c[k] - want[k]).abs() < 1e-6), "{x}: {c:?}");
        }
        // Built in or not, every name errs the same way when unknown, with the way out.
        let e = TransferFunction::preset("Black-Body Radiation")
            .unwrap_err()
            .to_string();
        assert!(e.contains("Choose Preset") && e.contains("RdBu"), "{e}");
        assert!(TransferFunction::preset("viridis_r_r").is_err());
    }

    #[test]
    fn paraview_json() {
        let j = r#"[{"Name":"Mine","ColorSpace":"RGB","RGBPoints":[-1,0,0,0, 1,1,0.5,0],
                    "Points":[-1,0,0.5,0, 1,0.8,0.5,0]}]"#;
        let tf = TransferFunction::from_paraview_json(j, "mine.json")
            .unwrap()
            .with_range(0.0, 4.0)
            .unwrap();
        let (c, a) = tf.eval(2.0);
        assert!((c[1] - 0.25).abs() < 1e-12 && (a - 0.4).abs() < 1e-12);
        assert!(TransferFunction::from_paraview_json("{\"RGBPoints\":[1,2]}", "x.json").is_err());
    }

    #[test]
    fn opacity_correction_composes() {
        let tf = TransferFunction::preset("viridis").unwrap();
        // Two half steps must equal one full step.
        let a = 0.3;
        let half = tf.step_alpha(a, 0.5);
        assert!((1.0 - (1.0 - half) * (1.0 - half) - a).abs() < 1e-12);
    }
}
