//! The [`Scene`]: particles, camera and transfer function, and what renders of them reuse.

use std::time::Instant;

use fluidcast_lod::LodHierarchy;
use fluidcast_render::SURFACE_THRESHOLD;
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction};

use crate::march::MarchState;
use crate::BackendError;

/// What one view's level of detail did: for a front-end's render line and statistics.
#[derive(Debug, Clone, PartialEq)]
pub struct LodReport {
    /// The tolerance: the largest cell edge taken, in pixels at a node's nearest depth.
    pub tolerance: f64,
    /// Particles at full detail.
    pub full_detail: usize,
    /// Particles the cut renders.
    pub rendered: usize,
    /// Nodes taken from each level (0: full detail).
    pub per_level: Vec<usize>,
    /// Levels of the hierarchy, full detail included.
    pub levels: usize,
    /// Milliseconds to build the hierarchy (when this render built it; else its first build).
    pub build_ms: f64,
    /// Milliseconds to make this view's cut.
    pub cut_ms: f64,
    /// Bytes the hierarchy holds.
    pub hierarchy_bytes: usize,
}

impl LodReport {
    /// One line for a user: "level of detail 4 px: 14962 of 42282 particles (35.4%; …)".
    pub fn line(&self) -> String {
        format!(
            "level of detail {} px: {} of {} particles ({:.1}%; per level {:?}), hierarchy of {} levels built in {:.0} ms, cut in {:.0} ms",
            self.tolerance,
            self.rendered,
            self.full_detail,
            100.0 * self.rendered as f64 / self.full_detail.max(1) as f64,
            self.per_level,
            self.levels,
            self.build_ms,
            self.cut_ms
        )
    }
}

/// The particles' level-of-detail hierarchy (built from a copy: the particles as given stay
/// for renders without level of detail, and for cuts that merge nothing) and how long it
/// took to build, in milliseconds.
struct Lod {
    h: LodHierarchy,
    build_ms: f64,
}

/// One view's cut through the hierarchy and what it depends on besides the particles.
pub(crate) struct Cut {
    key: (Camera, (u32, u32), u64),
    /// `None`: the cut merged nothing, and the particles as given are drawn.
    pub particles: Option<Particles>,
    surface: Option<Vec<bool>>,
    pub report: LodReport,
}

impl Cut {
    /// The cut's surface flags, if computed.
    pub fn surface_flags(&self) -> Option<&[bool]> {
        self.surface.as_deref()
    }

    /// Computes the cut's surface flags, if it has particles of its own.
    pub fn surface(&mut self) {
        if let (Some(p), None) = (&self.particles, &self.surface) {
            self.surface = Some(p.surface_flags(SURFACE_THRESHOLD));
        }
    }
}

/// Particles with their camera and transfer function, and what renders of them reuse: the
/// particles' surface flags, their level-of-detail hierarchy and the last view's cut, the
/// RBF field's BVH and progressive passes. A front-end keeps one per data set and sets
/// `camera` and `tf` per frame; new particles make a new scene.
pub struct Scene {
    particles: Particles,
    lod: Option<Lod>,
    /// The view (world units).
    pub camera: Camera,
    /// Colour and opacity over the rendered attribute's range.
    pub tf: TransferFunction,
    /// The particles' surface flags (with [`SURFACE_THRESHOLD`]), once computed.
    surface: Option<Vec<bool>>,
    pub(crate) cut: Option<Cut>,
    pub(crate) march: MarchState,
}

impl Scene {
    /// A scene of `particles` seen by `camera` through `tf`.
    pub fn new(particles: Particles, camera: Camera, tf: TransferFunction) -> Scene {
        Scene {
            particles,
            lod: None,
            camera,
            tf,
            surface: None,
            cut: None,
            march: MarchState::default(),
        }
    }

    /// The particles at full detail.
    pub fn particles(&self) -> &Particles {
        &self.particles
    }

    /// Computes what renders of these particles at full detail share and no view changes
    /// (their surface flags, [`SURFACE_THRESHOLD`]) now rather than in the first render:
    /// what the VTK mapper and a benchmark do once per time step.
    pub fn prepare(&mut self) {
        self.with_surface();
    }

    /// The particles' surface flags, if computed.
    pub(crate) fn surface_flags(&self) -> Option<&[bool]> {
        self.surface.as_deref()
    }

    /// The particles, transfer function and camera, and the march's state, apart.
    pub(crate) fn parts(&mut self) -> (&Particles, &TransferFunction, &Camera, &mut MarchState) {
        (&self.particles, &self.tf, &self.camera, &mut self.march)
    }

    /// The particles and their surface flags (computed on first use).
    pub(crate) fn with_surface(&mut self) -> (&Particles, &[bool]) {
        let p = &self.particles;
        let flags = self
            .surface
            .get_or_insert_with(|| p.surface_flags(SURFACE_THRESHOLD));
        (p, flags)
    }

    /// The cut of the particles' hierarchy for this camera at `size` and `tolerance` pixels:
    /// the hierarchy is built on first use, the cut kept for renders of the same view.
    pub(crate) fn cut_for(
        &mut self,
        size: (u32, u32),
        tolerance: f64,
    ) -> Result<&mut Cut, BackendError> {
        if self.lod.is_none() {
            let t = Instant::now();
            let h = LodHierarchy::build(self.particles.clone())?;
            let build_ms = t.elapsed().as_secs_f64() * 1e3;
            self.lod = Some(Lod { h, build_ms });
        }
        let Some(Lod { h, build_ms }) = &self.lod else {
            return Err(BackendError::Plan("level of detail: no hierarchy".into()));
        };
        let key = (self.camera.clone(), size, tolerance.to_bits());
        let fresh = !self.cut.as_ref().is_some_and(|c| c.key == key);
        if fresh {
            let t = Instant::now();
            let frame = self.camera.frame(size.0, size.1)?;
            let c = h.cut(&frame, tolerance)?;
            let merged = !c.is_full_detail();
            let report = LodReport {
                tolerance,
                full_detail: h.full_detail().len(),
                rendered: c.particles.len(),
                per_level: c.per_level,
                levels: h.levels(),
                build_ms: *build_ms,
                cut_ms: t.elapsed().as_secs_f64() * 1e3,
                hierarchy_bytes: h.memory_bytes(),
            };
            self.cut = Some(Cut {
                key,
                particles: merged.then_some(c.particles),
                surface: None,
                report,
            });
        }
        self.cut
            .as_mut()
            .ok_or_else(|| BackendError::Plan("level of detail: no cut".into()))
    }
}
