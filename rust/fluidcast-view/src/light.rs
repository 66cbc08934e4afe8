//! Local illumination of surfaces (and lit volume samples) in vtkVolumeProperty's terms.

/// Where the light comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Light {
    /// A light at the camera shining along the view direction (VTK's headlight, ParaView's
    /// "Light Kit" off): every lit surface facing the viewer is lit head on.
    Headlight,
    /// A directional light at infinity: the world-space direction from the scene toward the
    /// light (as vtkLight's position minus focal point with positional off); any length > 0.
    Directional([f64; 3]),
}

/// Blinn–Phong shading with vtkVolumeProperty's coefficients and defaults (Ambient 0.1,
/// Diffuse 0.7, Specular 0.2, SpecularPower 10) and a white light of intensity 1:
/// `ambient·C + diffuse·C·max(n·l, 0) + specular·max(n·h, 0)^power`, `h` the half vector of
/// `l` and the direction to the eye. Two-sided: a normal facing away from the eye is flipped,
/// as VTK's volume shaders do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lighting {
    /// Ambient coefficient (>= 0).
    pub ambient: f64,
    /// Diffuse coefficient (>= 0).
    pub diffuse: f64,
    /// Specular coefficient (>= 0).
    pub specular: f64,
    /// Specular exponent (>= 0).
    pub specular_power: f64,
    /// Where the light comes from.
    pub light: Light,
}

impl Default for Lighting {
    fn default() -> Self {
        Lighting {
            ambient: 0.1,
            diffuse: 0.7,
            specular: 0.2,
            specular_power: 10.0,
            light: Light::Headlight,
        }
    }
}

/// Why lighting parameters were refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LightingError {
    /// A coefficient (named) that is negative or not finite.
    #[error("{0} {1} must be finite and >= 0")]
    Coefficient(&'static str, f64),
    /// A light direction that is zero or not finite.
    #[error("light direction {0:?} must be finite and not zero")]
    Direction([f64; 3]),
}

fn normalise(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if l > 0.0 {
        v.map(|c| c / l)
    } else {
        v
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl Lighting {
    /// Checks the coefficients and the light direction.
    pub fn validate(&self) -> Result<(), LightingError> {
        let coefficients = [
            ("ambient", self.ambient),
            ("diffuse", self.diffuse),
            ("specular", self.specular),
            ("specular power", self.specular_power),
        ];
        for (what, v) in coefficients {
            if !(v.is_finite() && v >= 0.0) {
                return Err(LightingError::Coefficient(what, v));
            }
        }
        if let Light::Directional(d) = self.light {
            if !d.iter().all(|c| c.is_finite()) || d == [0.0; 3] {
                return Err(LightingError::Direction(d));
            }
        }
        Ok(())
    }

    /// The shaded colour of a surface of colour `c` with unit normal `n` (world space), seen
    /// along unit `to_eye` (from the surface toward the eye) by a camera looking along unit
    /// `forward`. Not clamped: a colour may exceed 1 where specular adds to it, as in VTK
    /// before the frame buffer clamps.
    pub fn shade(&self, c: [f64; 3], n: [f64; 3], to_eye: [f64; 3], forward: [f64; 3]) -> [f64; 3] {
        let n = if dot(n, to_eye) < 0.0 {
            n.map(|x| -x)
        } else {
            n
        };
        let l = self.direction(forward);
        let diffuse = self.diffuse * dot(n, l).max(0.0);
        let h = normalise([l[0] + to_eye[0], l[1] + to_eye[1], l[2] + to_eye[2]]);
        let nh = dot(n, h).max(0.0);
        let specular = if diffuse > 0.0 || self.light == Light::Headlight {
            self.specular * nh.powf(self.specular_power)
        } else {
            0.0 // no highlight on the side facing away from the light
        };
        c.map(|x| (self.ambient + diffuse) * x + specular)
    }

    /// A volume sample's colour lit as VTK's volume shaders light it with two-sided lighting:
    /// `|n·l|` and `|n·h|`, so a gradient and its opposite light alike (a sample's normal has
    /// no front: the field may grow toward the eye or away from it).
    pub fn shade_volume(
        &self,
        c: [f64; 3],
        n: [f64; 3],
        to_eye: [f64; 3],
        forward: [f64; 3],
    ) -> [f64; 3] {
        let l = self.direction(forward);
        let diffuse = self.diffuse * dot(n, l).abs();
        let h = normalise([l[0] + to_eye[0], l[1] + to_eye[1], l[2] + to_eye[2]]);
        let specular = self.specular * dot(n, h).abs().powf(self.specular_power);
        c.map(|x| (self.ambient + diffuse) * x + specular)
    }

    /// Unit direction from the scene toward the light for a camera looking along `forward`.
    fn direction(&self, forward: [f64; 3]) -> [f64; 3] {
        match self.light {
            Light::Headlight => forward.map(|x| -x),
            Light::Directional(d) => normalise(d),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FWD: [f64; 3] = [0.0, 0.0, -1.0];
    const EYE: [f64; 3] = [0.0, 0.0, 1.0];

    /// Head on under the headlight: ambient + diffuse + specular; at a grazing normal only
    /// ambient (plus the vanishing highlight); a normal facing away is flipped (two-sided).
    #[test]
    fn headlight_is_blinn_phong_with_vtk_defaults() {
        let l = Lighting::default();
        let c = [0.5, 0.25, 1.0];
        let head_on = l.shade(c, EYE, EYE, FWD);
        for k in 0..3 {
            assert!(
                (head_on[k] - (0.8 * c[k] + 0.2)).abs() < 1e-12,
                "{head_on:?}"
            );
        }
        assert_eq!(l.shade(c, [0.0, 0.0, -1.0], EYE, FWD), head_on);
        let grazing = l.shade(c, [1.0, 0.0, 0.0], EYE, FWD);
        for k in 0..3 {
            assert!((grazing[k] - 0.1 * c[k]).abs() < 1e-12, "{grazing:?}");
        }
        // At 60 degrees: diffuse by cos 60, the half vector is the eye, n·h = cos 60.
        let n = [60f64.to_radians().sin(), 0.0, 0.5];
        let s = l.shade([1.0; 3], n, EYE, FWD);
        let want = 0.1 + 0.7 * 0.5 + 0.2 * 0.5f64.powf(10.0);
        assert!((s[0] - want).abs() < 1e-12, "{s:?} vs {want}");
    }

    /// Volume lighting is two-sided by absolute values: a normal and its opposite light alike,
    /// head on under the headlight as a surface would.
    #[test]
    fn volume_lighting_is_two_sided() {
        let l = Lighting::default();
        let c = [0.5, 0.25, 1.0];
        let n = [0.6, 0.0, 0.8];
        let a = l.shade_volume(c, n, EYE, FWD);
        assert_eq!(a, l.shade_volume(c, n.map(|x| -x), EYE, FWD));
        let want = |k: usize| (0.1 + 0.7 * 0.8) * c[k] + 0.2 * 0.8f64.powf(10.0);
        for (k, got) in a.iter().enumerate() {
            assert!((got - want(k)).abs() < 1e-12, "{a:?}");
        }
        assert_eq!(l.shade_volume(c, EYE, EYE, FWD), l.shade(c, EYE, EYE, FWD));
    }

    /// A directional light lights what faces it and leaves what faces away at ambient, with
    /// no highlight there.
    #[test]
    fn directional_light_lights_the_side_facing_it() {
        let l = Lighting {
            light: Light::Directional([3.0, 0.0, 0.0]),
            ..Default::default()
        };
        let c = [1.0, 1.0, 1.0];
        let lit = l.shade(c, [1.0, 0.0, 0.0], EYE, FWD);
        assert!((lit[0] - (0.1 + 0.7 + 0.2 * 0.5f64.sqrt().powf(10.0))).abs() < 1e-12);
        let n = [-(0.5f64.sqrt()), 0.0, 0.5f64.sqrt()];
        let dark = l.shade(c, n, EYE, FWD);
        assert!((dark[0] - 0.1).abs() < 1e-12, "{dark:?}");
        assert!(l.validate().is_ok());
        let bad = Lighting {
            light: Light::Directional([0.0; 3]),
            ..Default::default()
        };
        assert!(bad.validate().is_err());
        let bad = Lighting {
            specular: f64::NAN,
            ..Default::default()
        };
        assert!(bad.validate().is_err());
    }
}
