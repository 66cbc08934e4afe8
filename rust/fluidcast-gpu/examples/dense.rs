use fluidcast_render::{plan_adaptive, render_adaptive, PlanParams, RenderParams};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction};
fn main() {
    let g = fluidcast_gpu::Gpu::new().unwrap();
    for (n, dz) in [
        (3000usize, 64u32),
        (1500, 64),
        (3000, 16),
        (5000, 16),
        (6000, 16),
        (9000, 16),
        (12000, 16),
        (20000, 4),
        (20000, 1),
    ] {
        let mut p = Particles::default();
        let mut s = 12345u32;
        let mut r = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32 - 0.5
        };
        for _ in 0..n {
            p.positions.push([0.1 * r(), 0.1 * r(), 0.1 * r()]);
            p.radii.push(0.05);
            p.volumes.push(1e-4);
            p.masses.push(1.0);
            p.values.push(r() + 0.5);
        }
        let mut tf = TransferFunction::preset("viridis")
            .unwrap()
            .with_range(0.0, 1.0)
            .unwrap();
        tf.unit_distance = 1.0;
        let cam = Camera {
            position: [0.0, 0.0, 0.6],
            focal_point: [0.0; 3],
            view_up: [0.0, 1.0, 0.0],
            ..Default::default()
        };
        let prm = RenderParams {
            width: 8,
            height: 8,
            adaptive: PlanParams {
                tolerance: None,
                ..Default::default()
            },
            grid: fluidcast_grid::GridParams {
                bundle: 8,
                depth_samples: dz,
            },
            ..Default::default()
        };
        let cpu = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        let planned = plan_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        let gr = match g.render_planned(&planned, &tf, &prm) {
            Ok(r) => r,
            Err(e) => {
                println!("n {n} dz {dz}: {e}");
                continue;
            }
        };
        let (c, _) = fluidcast_image::compare(&cpu.image, &gr.image, 1e-3).unwrap();
        if false {
            for k in 0..64 {
                let (a, b) = (cpu.image.rgba[k], gr.image.rgba[k]);
                if k % 9 == 0 {
                    println!("px {k}: cpu {:?} gpu {:?}", a, b);
                }
            }
        }
        let maxrefs = planned
            .grid
            .cells
            .iter()
            .map(|c| c.end - c.start)
            .max()
            .unwrap();
        let t = std::time::Instant::now();
        let _ = g.render_planned(&planned, &tf, &prm).unwrap();
        println!("n {n} dz {dz} ({:?}):", t.elapsed());
        println!(
            "n {n}: max refs/cell {maxrefs}, spans {}, max abs {:.3e}, samples cpu {} gpu {}",
            planned.grid.cells.len(),
            c.max_abs,
            cpu.stats.samples,
            gr.stats.samples
        );
    }
}
