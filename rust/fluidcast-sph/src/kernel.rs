use std::f64::consts::PI;
use std::fmt;
use std::str::FromStr;

/// A radially symmetric SPH smoothing kernel, normalised in 3D, with compact support.
///
/// All variants take the support radius `H` (the distance at which the kernel reaches zero).
/// `q = r / H` below.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Kernel {
    /// Cubic B-spline M4 (SPlisHSPlasH's `CubicKernel`, VTK's `vtkSPHCubicKernel` with
    /// `H = 2h`): `8/(πH³)·(6q³−6q²+1)` for `q ≤ ½`, `8/(πH³)·2(1−q)³` for `q ≤ 1`.
    #[default]
    CubicSpline,
    /// Quintic B-spline M6 (VTK's `vtkSPHQuinticKernel`, `H = 3h`, `s = 3q`):
    /// `1/(120πh³)·[(3−s)⁵ − 6(2−s)⁵ + 15(1−s)⁵]` with negative brackets dropped.
    Quintic,
    /// Wendland C2 (PySPH's `WendlandQuintic`, VTK's `vtkWendlandQuinticKernel`, `H = 2h`):
    /// `21/(2πH³)·(1−q)⁴(1+4q)`.
    WendlandC2,
    /// Wendland C4: `495/(32πH³)·(1−q)⁶(1+6q+35/3·q²)`.
    WendlandC4,
    /// Müller et al.'s poly6: `315/(64πH⁹)·(H²−r²)³`.
    Poly6,
    /// Gaussian with σ = H/3, truncated at 3σ = H and renormalised so that it integrates to
    /// exactly 1 over its support.
    Gaussian,
}

impl Kernel {
    /// Every kernel, for tests and help texts.
    pub const ALL: [Kernel; 6] = [
        Kernel::CubicSpline,
        Kernel::Quintic,
        Kernel::WendlandC2,
        Kernel::WendlandC4,
        Kernel::Poly6,
        Kernel::Gaussian,
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Kernel::CubicSpline => "cubic",
            Kernel::Quintic => "quintic",
            Kernel::WendlandC2 => "wendland-c2",
            Kernel::WendlandC4 => "wendland-c4",
            Kernel::Poly6 => "poly6",
            Kernel::Gaussian => "gaussian",
        }
    }

    /// Ratio of the support radius to the classic smoothing length h (`H = factor · h`),
    /// i.e. VTK's kernel `CutoffFactor`.
    pub fn support_factor(self) -> f64 {
        match self {
            Kernel::Quintic | Kernel::Gaussian => 3.0,
            _ => 2.0,
        }
    }

    /// `W(r, H)` in 1/length³; 0 for `r ≥ H`.
    #[inline]
    pub fn eval(self, r: f64, h: f64) -> f64 {
        let q = r / h;
        if q >= 1.0 {
            return 0.0;
        }
        let h3 = h * h * h;
        match self {
            Kernel::CubicSpline => {
                let k = 8.0 / (PI * h3);
                if q <= 0.5 {
                    k * (6.0 * q * q * q - 6.0 * q * q + 1.0)
                } else {
                    let t = 1.0 - q;
                    k * 2.0 * t * t * t
                }
            }
            Kernel::Quintic => {
                let s = 3.0 * q;
                let hh = h / 3.0;
                let p5 = |x: f64| if x > 0.0 { x.powi(5) } else { 0.0 };
                (p5(3.0 - s) - 6.0 * p5(2.0 - s) + 15.0 * p5(1.0 - s)) / (120.0 * PI * hh * hh * hh)
            }
            Kernel::WendlandC2 => {
                let t = 1.0 - q;
                21.0 / (2.0 * PI * h3) * t * t * t * t * (1.0 + 4.0 * q)
            }
            Kernel::WendlandC4 => {
                let t = 1.0 - q;
                495.0 / (32.0 * PI * h3) * t.powi(6) * (1.0 + 6.0 * q + 35.0 / 3.0 * q * q)
            }
            Kernel::Poly6 => {
                let d = 1.0 - q * q;
                315.0 / (64.0 * PI * h3) * d * d * d
            }
            Kernel::Gaussian => {
                // σ = H/3; normalisation of exp(-r²/2σ²) over the ball of radius 3σ:
                // (2π)^{3/2} σ³ [erf(3/√2) − √(2/π)·3·e^{−9/2}].
                let c = gaussian_normalisation();
                let sigma = h / 3.0;
                (-(r * r) / (2.0 * sigma * sigma)).exp() / (c * sigma * sigma * sigma)
            }
        }
    }

    /// The normalisation of `W(r, H) = norm(H) · shape(r/H)`, in 1/length³: computed once
    /// per particle by the ray casters, whose inner loops evaluate [`Kernel::shape`] only.
    #[inline]
    pub fn norm(self, h: f64) -> f64 {
        let h3 = h * h * h;
        match self {
            Kernel::CubicSpline => 8.0 / (PI * h3),
            Kernel::Quintic => 27.0 / (120.0 * PI * h3),
            Kernel::WendlandC2 => 21.0 / (2.0 * PI * h3),
            Kernel::WendlandC4 => 495.0 / (32.0 * PI * h3),
            Kernel::Poly6 => 315.0 / (64.0 * PI * h3),
            Kernel::Gaussian => 27.0 / (gaussian_normalisation() * h3),
        }
    }

    /// The dimensionless profile of `W` at `q = r/H` (see [`Kernel::norm`]); 0 for `q ≥ 1`.
    /// Written without data-dependent loops so that a loop over samples vectorises.
    #[inline(always)]
    pub fn shape(self, q: f64) -> f64 {
        let t = 1.0 - q;
        let v = match self {
            Kernel::CubicSpline => {
                let near = 6.0 * q * q * q - 6.0 * q * q + 1.0;
                if q <= 0.5 {
                    near
                } else {
                    2.0 * t * t * t
                }
            }
            Kernel::Quintic => {
                let s = 3.0 * q;
                let p5 = |x: f64| {
                    let x = x.max(0.0);
                    x * x * x * x * x
                };
                p5(3.0 - s) - 6.0 * p5(2.0 - s) + 15.0 * p5(1.0 - s)
            }
            Kernel::WendlandC2 => t * t * t * t * (1.0 + 4.0 * q),
            Kernel::WendlandC4 => {
                let t2 = t * t;
                t2 * t2 * t2 * (1.0 + 6.0 * q + 35.0 / 3.0 * q * q)
            }
            Kernel::Poly6 => {
                let d = 1.0 - q * q;
                d * d * d
            }
            Kernel::Gaussian => (-4.5 * q * q).exp(),
        };
        if q < 1.0 {
            v
        } else {
            0.0
        }
    }

    /// `d shape / dq` at `q = r/H` (0 for `q ≥ 1`), so that the gradient of `W(|x − c|, H)`
    /// with respect to `x` is `norm(H) · shape'(q) / H · (x − c)/|x − c|`: what analytic field
    /// gradients (iso-surface normals, shading) are made of.
    #[inline]
    pub fn shape_slope(self, q: f64) -> f64 {
        if !(0.0..1.0).contains(&q) {
            return 0.0;
        }
        let t = 1.0 - q;
        match self {
            Kernel::CubicSpline if q <= 0.5 => 18.0 * q * q - 12.0 * q,
            Kernel::CubicSpline => -6.0 * t * t,
            Kernel::Quintic => {
                let s = 3.0 * q;
                let p4 = |x: f64| {
                    let x = x.max(0.0);
                    x * x * x * x
                };
                -15.0 * (p4(3.0 - s) - 6.0 * p4(2.0 - s) + 15.0 * p4(1.0 - s))
            }
            Kernel::WendlandC2 => -20.0 * q * t * t * t,
            Kernel::WendlandC4 => -56.0 / 3.0 * q * t.powi(5) * (1.0 + 5.0 * q),
            Kernel::Poly6 => {
                let d = 1.0 - q * q;
                -6.0 * q * d * d
            }
            Kernel::Gaussian => -9.0 * q * (-4.5 * q * q).exp(),
        }
    }

    /// `W` at single precision for the renderer's inner loops.
    #[inline]
    pub fn eval_f32(self, r: f32, h: f32) -> f32 {
        self.eval(r as f64, h as f64) as f32
    }
}

/// ∫ exp(−r²/2σ²) dV over the ball of radius 3σ, divided by σ³:
/// (2π)^{3/2} [erf(3/√2) − √(2/π)·3·e^{−9/2}].
fn gaussian_normalisation() -> f64 {
    static C: std::sync::OnceLock<f64> = std::sync::OnceLock::new();
    *C.get_or_init(|| {
        (2.0 * PI).powf(1.5)
            * (libm::erf(3.0 / std::f64::consts::SQRT_2)
                - (2.0 / PI).sqrt() * 3.0 * (-4.5f64).exp())
    })
}

impl fmt::Display for Kernel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Kernel {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.to_ascii_lowercase().replace('_', "-");
        Ok(match s.as_str() {
            "cubic" | "cubic-spline" | "m4" => Kernel::CubicSpline,
            "quintic" | "quintic-spline" | "m6" => Kernel::Quintic,
            "wendland-c2" | "wendland" | "wendland-quintic" | "c2" => Kernel::WendlandC2,
            "wendland-c4" | "c4" => Kernel::WendlandC4,
            "poly6" => Kernel::Poly6,
            "gaussian" | "gauss" => Kernel::Gaussian,
            _ => {
                return Err(format!(
                    "unknown kernel '{s}' (expected one of: {})",
                    Kernel::ALL.map(|k| k.name()).join(", ")
                ))
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ W dV = 4π ∫₀ᴴ r² W(r) dr, by composite Simpson with many intervals.
    fn integral(k: Kernel, h: f64) -> f64 {
        let n = 20_000;
        let dr = h / n as f64;
        let f = |r: f64| 4.0 * PI * r * r * k.eval(r, h);
        let mut s = f(0.0) + f(h);
        for i in 1..n {
            s += if i % 2 == 1 { 4.0 } else { 2.0 } * f(i as f64 * dr);
        }
        s * dr / 3.0
    }

    #[test]
    fn norm_times_shape_is_the_kernel() {
        for k in Kernel::ALL {
            for h in [0.01, 0.7, 3.0] {
                for i in 0..=1100 {
                    let q = i as f64 / 1000.0;
                    let (want, got) = (k.eval(q * h, h), k.norm(h) * k.shape(q));
                    assert!(
                        (got - want).abs() <= 1e-13 * want.abs().max(k.norm(h)),
                        "{k} h {h} q {q}: {got} vs {want}"
                    );
                }
            }
        }
    }

    /// The slope against central differences of the shape, inside the support (where every
    /// kernel is smooth but at the cubic's and quintic's joins, which are C² so the
    /// difference still converges) and 0 beyond it.
    #[test]
    fn shape_slope_is_the_derivative_of_the_shape() {
        for k in Kernel::ALL {
            let e = 1e-6;
            for i in 1..1000 {
                let q = i as f64 / 1000.0;
                let (lo, hi) = ((q - e).max(0.0), (q + e).min(1.0 - 1e-15));
                let fd = (k.shape(hi) - k.shape(lo)) / (hi - lo);
                let got = k.shape_slope(q);
                assert!(
                    (got - fd).abs() <= 1e-5 * fd.abs().max(1.0),
                    "{k} q {q}: {got} vs {fd}"
                );
            }
            assert_eq!(k.shape_slope(1.0), 0.0);
            assert_eq!(k.shape_slope(2.5), 0.0);
            assert_eq!(k.shape_slope(0.0), 0.0, "{k}: a smooth peak at the centre");
        }
    }

    #[test]
    fn every_kernel_integrates_to_one() {
        for k in Kernel::ALL {
            for h in [0.05, 1.0, 7.0] {
                let i = integral(k, h);
                assert!((i - 1.0).abs() < 1e-4, "{k} with H={h}: {i}");
            }
        }
    }

    #[test]
    fn compact_support_and_positive() {
        for k in Kernel::ALL {
            assert_eq!(k.eval(1.0, 1.0), 0.0);
            assert_eq!(k.eval(1.5, 1.0), 0.0);
            assert!(k.eval(0.0, 1.0) > 0.0);
            assert!(k.eval(0.99, 1.0) >= 0.0);
            assert_eq!(k.name().parse::<Kernel>().unwrap(), k);
        }
    }

    #[test]
    fn cubic_matches_vtk_form() {
        // VTK: W = 1/(πh³)(1 - 1.5q² + 0.75q³), q = r/h < 1, H = 2h.
        let h = 0.025;
        let r = 0.01;
        let q = r / h;
        let vtk = 1.0 / (PI * h * h * h) * (1.0 - 1.5 * q * q + 0.75 * q * q * q);
        assert!((Kernel::CubicSpline.eval(r, 2.0 * h) - vtk).abs() < 1e-9 * vtk);
    }

    /// Each kernel against its published form in the smoothing length h (H = factor · h),
    /// written out here independently of `eval`: PySPH's WendlandQuintic and
    /// WendlandQuinticC4 (q = r/h ≤ 2), VTK's vtkSPHQuinticKernel (q ≤ 3), Müller et al.'s poly6
    /// in H, and the Gaussian's shape exp(−r²/2σ²), σ = H/3, relative to its centre.
    #[test]
    fn every_kernel_has_its_published_shape() {
        let h = 0.37;
        for i in 0..200 {
            let r = i as f64 / 200.0 * 2.0 * h;
            let q = r / h;
            let c2 = 21.0 / (16.0 * PI * h.powi(3)) * (1.0 - q / 2.0).powi(4) * (2.0 * q + 1.0);
            let c4 = 495.0 / (256.0 * PI * h.powi(3))
                * (1.0 - q / 2.0).powi(6)
                * (35.0 / 12.0 * q * q + 3.0 * q + 1.0);
            let big = 2.0 * h;
            let poly6 = 315.0 / (64.0 * PI * big.powi(9)) * (big * big - r * r).powi(3);
            for (k, want) in [
                (Kernel::WendlandC2, c2),
                (Kernel::WendlandC4, c4),
                (Kernel::Poly6, poly6),
            ] {
                let got = k.eval(r, 2.0 * h);
                assert!(
                    (got - want).abs() <= 1e-12 * want.max(1.0),
                    "{k} r {r}: {got} vs {want}"
                );
            }
        }
        for i in 0..300 {
            let r = i as f64 / 300.0 * 3.0 * h;
            let q = r / h;
            let p5 = |x: f64| x.max(0.0).powi(5);
            let want =
                (p5(3.0 - q) - 6.0 * p5(2.0 - q) + 15.0 * p5(1.0 - q)) / (120.0 * PI * h.powi(3));
            let got = Kernel::Quintic.eval(r, 3.0 * h);
            assert!(
                (got - want).abs() <= 1e-12 * want.max(1.0),
                "quintic r {r}: {got} vs {want}"
            );
            let big = 3.0 * h;
            let g = Kernel::Gaussian;
            let ratio = g.eval(r, big) / g.eval(0.0, big);
            let sigma = big / 3.0;
            let want = (-r * r / (2.0 * sigma * sigma)).exp();
            assert!(
                (ratio - want).abs() < 1e-12,
                "gaussian r {r}: {ratio} vs {want}"
            );
        }
    }
}
