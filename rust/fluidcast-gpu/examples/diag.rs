use fluidcast_render::{plan_adaptive, render_adaptive, PlanParams, RenderParams};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction};
use std::collections::BTreeMap;

fn main() {
    let path = std::env::args().nth(1).unwrap();
    let elev: f64 = std::env::args()
        .nth(2)
        .unwrap_or("0".into())
        .parse()
        .unwrap();
    let ds = fluidcast_io::read_dataset(std::path::Path::new(&path)).unwrap();
    let spec = fluidcast_sph::ParticleSpec {
        quantity: Some("velocity:mag".parse().unwrap()),
        ..Default::default()
    };
    let p = Particles::from_dataset(&ds, &spec).unwrap();
    let (lo, hi) = p.value_range();
    let mut tf = TransferFunction::preset("viridis")
        .unwrap()
        .with_range(lo as f64, hi as f64)
        .unwrap();
    let (a, b) = p.support_bounds();
    let diag = (0..3)
        .map(|k| ((b[k] - a[k]) as f64).powi(2))
        .sum::<f64>()
        .sqrt();
    tf.unit_distance = diag / (p.len() as f64).cbrt();
    let mut cam = Camera::default();
    cam.reset(a.map(f64::from), b.map(f64::from));
    cam.elevation(elev);
    cam.orthogonalize_view_up();
    let g = fluidcast_gpu::Gpu::new().unwrap();
    let w: u32 = std::env::args()
        .nth(3)
        .unwrap_or("200".into())
        .parse()
        .unwrap();
    let h: u32 = std::env::args()
        .nth(4)
        .unwrap_or("150".into())
        .parse()
        .unwrap();
    let prm = RenderParams {
        width: w,
        height: h,
        adaptive: PlanParams {
            tolerance: None,
            ..Default::default()
        },
        ..Default::default()
    };
    let cpu = plan_adaptive(&p, None, &cam, &tf, &prm).unwrap();
    let (r, d) = g.render_with_dump(&p, None, &cam, &tf, &prm).unwrap();
    let cr = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
    let (c, _) = fluidcast_image::compare(&cr.image, &r.image, 1.0 / 255.0).unwrap();
    println!(
        "full gpu vs cpu: max {} samples cpu {} gpu {}",
        c.max_abs, cr.stats.samples, r.stats.samples
    );
    let rp = g.render_planned(&cpu, &tf, &prm).unwrap();
    let (c2, _) = fluidcast_image::compare(&cr.image, &rp.image, 1.0 / 255.0).unwrap();
    println!(
        "gpu caster on cpu plan: max {} samples {}",
        c2.max_abs, rp.stats.samples
    );
    // cells
    let g2 = &cpu.grid;
    let mut cc = BTreeMap::new();
    for bb in 0..g2.bundle_count() {
        for c in g2.bundle_cells(bb) {
            let mut u = g2.refs[c.start as usize..c.unique_end as usize].to_vec();
            u.sort();
            let mut m = g2.refs[c.unique_end as usize..c.end as usize].to_vec();
            m.sort();
            cc.insert((bb as u32, c.z), (u, m));
        }
    }
    let mut gc = BTreeMap::new();
    for (k, c) in d.cells.iter().enumerate() {
        let u = d.refs[c.start as usize..c.unique_end as usize].to_vec();
        let m = d.refs[c.unique_end as usize..c.end as usize].to_vec();
        gc.insert((d.cell_bundles[k], c.z), (u, m));
    }
    let keys: std::collections::BTreeSet<_> = cc.keys().chain(gc.keys()).collect();
    let mut n = 0;
    for k in keys {
        if cc.get(k) != gc.get(k) {
            n += 1;
            if n < 4 {
                let f = |x: Option<&(Vec<u32>, Vec<u32>)>| x.map(|(u, m)| (u.len(), m.len()));
                println!(
                    "cell {:?}: cpu {:?} gpu {:?}",
                    k,
                    f(cc.get(k)),
                    f(gc.get(k))
                );
                if let (Some(a), Some(b)) = (cc.get(k), gc.get(k)) {
                    let sa: std::collections::BTreeSet<_> = a.0.iter().chain(&a.1).collect();
                    let sb: std::collections::BTreeSet<_> = b.0.iter().chain(&b.1).collect();
                    println!(
                        "   only cpu {:?} only gpu {:?}",
                        sa.difference(&sb).take(5).collect::<Vec<_>>(),
                        sb.difference(&sa).take(5).collect::<Vec<_>>()
                    );
                }
            }
        }
    }
    println!(
        "{} of {} cells differ; pairs cpu {} gpu {}",
        n,
        cc.len().max(gc.len()),
        g2.refs.len(),
        d.refs.len()
    );

    // worst pixel
    let w = prm.width;
    let mut worst = (0.0f32, 0usize);
    for (k, (a, b)) in cr.image.rgba.iter().zip(&rp.image.rgba).enumerate() {
        let d = (0..4).map(|c| (a[c] - b[c]).abs()).fold(0.0, f32::max);
        if d > worst.0 {
            worst = (d, k);
        }
    }
    let mut lost = std::collections::BTreeMap::new();
    for (k, (a, b)) in cr.image.rgba.iter().zip(&rp.image.rgba).enumerate() {
        if a[3] > 0.01 && b[3] == 0.0 {
            let (x, y) = (k as u32 % w, k as u32 / w);
            *lost.entry((x / 8, y / 8)).or_insert(0) += 1;
        }
    }
    println!("lost pixels by bundle: {:?}", lost);
    for (&(bx, by), _) in lost.iter().take(3) {
        let bb = (by * cpu.grid.bundles_x + bx) as usize;
        let cells = cpu.grid.bundle_cells(bb);
        println!(
            "bundle {bb}: {} cells, refs {:?}, spans {:?}",
            cells.len(),
            cells
                .iter()
                .map(|c| (c.z, c.end - c.start))
                .collect::<Vec<_>>(),
            cpu.plan.bundle_spans(bb).len()
        );
    }
    let (pi, pj) = ((worst.1 as u32) % w, (worst.1 as u32) / w);
    println!(
        "worst pixel ({pi}, {pj}) diff {} cpu {:?} gpu {:?}",
        worst.0, cr.image.rgba[worst.1], rp.image.rgba[worst.1]
    );
    let grid = &cpu.grid;
    let d = grid.params.bundle;
    let bb = ((pj / d) * grid.bundles_x + pi / d) as usize;
    let ray = fluidcast_grid::Ray::through_pixel(&grid.frame, pi, pj);
    let zs = &grid.depths.as_ref().unwrap().z;
    let dz = grid.params.depth_samples as usize;
    // f32 ray as the shader
    let x = 2.0 * (pi as f32 + 0.5) / w as f32 - 1.0;
    let y = 1.0 - 2.0 * (pj as f32 + 0.5) / prm.height as f32;
    let fr = &grid.frame;
    let o32 = [0f32; 3];
    let d32 = [
        x * fr.tan_half as f32 * fr.aspect as f32,
        y * fr.tan_half as f32,
        1.0f32,
    ];
    println!("ray d64 {:?} d32 {:?}", ray.d, d32);
    let (mut t64, mut n64, mut done64) = (1f64, 0, false);
    for s in cpu.plan.bundle_spans(bb) {
        let c = &grid.cells[s.first as usize];
        let k0 = c.z as usize * dz;
        let refs: Vec<u32> = grid
            .merged_refs(&grid.cells[s.first as usize..(s.first + s.count) as usize])
            .collect();
        for m in 0..dz {
            let z = zs[k0 + m];
            let z32 = z as f32;
            let (mut s64, mut s32) = (0f64, 0f32);
            let (mut hit64, mut hit32) = (0, 0);
            for &r in &refs {
                let p = &grid.particles[r as usize];
                let w64 = prm.kernel.eval(ray.distance_at(z, p), p.h);
                if w64 > 0.0 {
                    s64 += p.v * w64;
                    hit64 += 1;
                }
                let pc = [p.c[0] as f32, p.c[1] as f32, p.c[2] as f32];
                let q = [
                    o32[0] + z32 * d32[0] - pc[0],
                    o32[1] + z32 * d32[1] - pc[1],
                    o32[2] + z32 * d32[2] - pc[2],
                ];
                let dist = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
                let h32 = p.h as f32;
                let oc = [o32[0] - pc[0], o32[1] - pc[1], o32[2] - pc[2]];
                let dd32 = d32[0] * d32[0] + d32[1] * d32[1] + d32[2] * d32[2];
                let bq = d32[0] * oc[0] + d32[1] * oc[1] + d32[2] * oc[2];
                let cq = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - h32 * h32;
                let disc = bq * bq - dd32 * cq;
                let inside = disc > 0.0 && {
                    let sq = disc.sqrt();
                    z32 >= (-bq - sq) / dd32 && z32 <= (-bq + sq) / dd32
                };
                let w32 = if inside {
                    prm.kernel.eval(dist as f64, p.h as f32 as f64) as f32
                } else {
                    0.0
                };
                if w32 > 0.0 {
                    s32 += p.v as f32 * w32;
                    hit32 += 1;
                }
            }
            if s64 > 0.0 && !done64 {
                let mut wq = 0f64;
                for &r in &refs {
                    let p = &grid.particles[r as usize];
                    let w = prm.kernel.eval(ray.distance_at(z, p), p.h);
                    if w > 0.0 {
                        wq += p.v * p.a * w;
                    }
                }
                let q = wq / s64;
                let (_rgb, al) = tf.eval(q);
                let zb = zs[k0 + m + 1];
                let a = tf.step_alpha(al, (zb - z) * ray.dlen);
                t64 *= 1.0 - a;
                n64 += 1;
                if t64 < prm.min_transmittance {
                    done64 = true;
                }
                println!(
                    "  z{} m{} q {q:.4} a {a:.4} T {t64:.4} refs {}",
                    c.z,
                    m,
                    refs.len()
                );
            }
            if (s64 > 0.0) != (s32 > 0.0) || hit64 != hit32 {
                println!(
                    "span first {} z {} m {m}: s64 {s64:e} ({hit64}) s32 {s32:e} ({hit32})",
                    s.first, c.z
                );
            }
        }
    }
    println!("emulated alpha {} samples {n64}", 1.0 - t64);

    // Every pixel that differs by more than 1e-3: does its ray have an edge sample (every
    // contributing particle within 1e-4 H of its support edge, in f64 or f32)?
    let (mut differ, mut explained, mut explained_opaque) = (0, 0, 0);
    for (k, (a, b)) in cr.image.rgba.iter().zip(&rp.image.rgba).enumerate() {
        let dmax = (0..4).map(|c| (a[c] - b[c]).abs()).fold(0.0, f32::max);
        if dmax <= 1e-3 {
            continue;
        }
        differ += 1;
        let (pi, pj) = (k as u32 % w, k as u32 / w);
        let bb = ((pj / d) * grid.bundles_x + pi / d) as usize;
        let ray = fluidcast_grid::Ray::through_pixel(&grid.frame, pi, pj);
        let mut edge = false;
        let mut opaque = false;
        for s in cpu.plan.bundle_spans(bb) {
            let c = &grid.cells[s.first as usize];
            let k0 = c.z as usize * dz;
            let refs: Vec<u32> = grid
                .merged_refs(&grid.cells[s.first as usize..(s.first + s.count) as usize])
                .collect();
            for m in 0..dz * s.count as usize {
                let z = zs[k0 + m];
                let (mut inner, mut near_edge) = (0, 0);
                let (mut ws, mut wq) = (0.0f64, 0.0f64);
                for &r in &refs {
                    let p = &grid.particles[r as usize];
                    let q = ray.distance_at(z, p) / p.h;
                    if q < 1.0 - 1e-4 {
                        inner += 1;
                    } else if q < 1.0 + 1e-4 {
                        near_edge += 1;
                    }
                    let wgt = prm.kernel.eval(ray.distance_at(z, p), p.h);
                    ws += p.v * wgt;
                    wq += p.v * p.a * wgt;
                }
                if inner == 0 && near_edge > 0 {
                    edge = true;
                }
                if ws > 0.0 && tf.eval(wq / ws).1 > 0.999 {
                    opaque = true;
                }
            }
        }
        explained += edge as usize;
        explained_opaque += (opaque && !edge) as usize;
    }
    println!("{differ} pixels differ by > 1e-3 (caster on the CPU plan); {explained} have an edge sample on their ray, {explained_opaque} more a sample of opacity > 0.999");
}
