//! Diagnostic: where and how blood leaves an intact capsule. Relaxes the scenario (kept in
//! /tmp/perfuse-probe-cache2 between runs), steps it to T_END on the CPU, prints per FRAME the liquid
//! outside (nˢ < 0.05), leaving (nˢ < 0.12) and beyond the capsule's local hull
//! (`analysis::capsule::beyond_capsule`), then each leaving particle's history: position,
//! velocity, fractions, pressure and its signed distance along the outward normal of its nearest
//! membrane particle. `TRACE_RELAX=1` traces the relaxation instead (t < 0); `IDS=a,b,…` picks the
//! particles, `BEYOND=1` those beyond the capsule at the end. Found the liver's seepage through its lower face (README: deviations, the capsule's layers).
//!
//! ```text
//! cargo run --release --example seep_probe -- SCENARIO T_END FRAME [k=v]...
//! ```

use perfuse::replay::relaxed_cache::{RelaxedCache, relax_with_cache};
use perfuse::scenario::{Scenario, SolidFlags};
use perfuse::sim::{BackendKind, Simulation};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        return Err("usage: seep_probe SCENARIO T_END FRAME [k=v]...".into());
    }
    let path = Path::new(&args[1]);
    let t_end: f64 = args[2].parse()?;
    let frame: f64 = args[3].parse()?;
    let sets: Vec<String> = args[4..].iter().filter(|a| *a != "--set").cloned().collect();
    let sc = Scenario::load_with_overrides(path, &sets)?;
    let generated = perfuse::scenario::generate(&sc);
    let normal0 = generated.solid_normal.clone();
    let mut sim = Simulation::from_generated(&sc, generated, BackendKind::Cpu)?;
    let cache = RelaxedCache::new("/tmp/perfuse-probe-cache2");
    let t0 = std::time::Instant::now();
    let dx = sim.params().dx_solid;
    let mut frames = Vec::new();
    let trace_relax = std::env::var("TRACE_RELAX").is_ok();
    if trace_relax {
        let r = sc.relaxation.clone().ok_or("no relaxation")?;
        for c in r.start_commands() {
            sim.apply(&c)?;
        }
        let mut t = sim.time();
        loop {
            let s = sim.read_state()?;
            eprintln!("relax t {:.3} ({:.0} s)", s.t, t0.elapsed().as_secs_f64());
            frames.push((
                s.t,
                s.liquid.clone().in_id_order(),
                s.solid.clone().in_id_order(),
                s.solid_extra.flags.clone(),
            ));
            if t >= -1e-9 {
                break;
            }
            t = (t + frame).min(0.0);
            sim.advance_until(t, u64::MAX, |_| {})?;
        }
        for c in r.end_commands() {
            sim.apply(&c)?;
        }
    } else {
        let from = relax_with_cache(Some(&cache), false, &sc, &mut sim, |_| {})?;
        eprintln!("relaxed ({from:?}) in {:.0} s", t0.elapsed().as_secs_f64());
    }
    let mut last_beyond: Vec<u32>;
    let mut t = sim.time();
    loop {
        let s = sim.read_state()?;
        let st_l = s.liquid.clone().in_id_order();
        let outside = st_l.n_s.iter().filter(|&&n| n < 0.05).count();
        let leaving = st_l.n_s.iter().filter(|&&n| n < 0.12).count();
        let beyond: Vec<u32> =
            perfuse::analysis::capsule::beyond_capsule(&s, &normal0, dx).into_iter().map(|i| s.liquid.id[i]).collect();
        eprintln!(
            "t {:.3} steps {} outside {} leaving {} beyond the capsule {} broken {} ({:.0} s)",
            s.t,
            s.steps,
            outside,
            leaving,
            beyond.len(),
            s.broken_bonds(),
            t0.elapsed().as_secs_f64()
        );
        if std::env::var("BBOX").is_ok() {
            let bb = |v: &[glam::Vec3]| {
                v.iter().fold((glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN)), |(a, b), p| {
                    (a.min(*p), b.max(*p))
                })
            };
            eprintln!("  solid bbox {:?} liquid bbox {:?}", bb(&s.solid.pos), bb(&st_l.pos));
        }
        frames.push((s.t, st_l, s.solid.clone().in_id_order(), s.solid_extra.flags.clone()));
        if std::env::var("NEIGH").is_ok() && t >= t_end - 1e-9 {
            let torn: Vec<usize> = (0..s.solid.len())
                .filter(|&k| s.solid_extra.flags[k] & SolidFlags::MEMBRANE != 0)
                .filter(|&k| {
                    !perfuse::sim::cpu::forces::capsule_seals(s.solid_extra.bonds[k], s.solid_extra.bonds_initial[k])
                })
                .collect();
            let n_memb = (0..s.solid.len()).filter(|&k| s.solid_extra.flags[k] & SolidFlags::MEMBRANE != 0).count();
            eprintln!("membrane particles {n_memb}, not intact (< 3/4 bonds) {}", torn.len());
            for &k in torn.iter().take(60) {
                eprintln!(
                    "   torn {k} at {:+.4?} n0 {:+.2?} bonds {}/{}",
                    s.solid.pos[k], normal0[k], s.solid_extra.bonds[k], s.solid_extra.bonds_initial[k]
                );
            }
            // the solid around each particle beyond the capsule: offset/Δx, membrane, cof(F)n̂₀, bonds
            for i in perfuse::analysis::capsule::beyond_capsule(&s, &normal0, dx) {
                let x = s.liquid.pos[i];
                eprintln!("beyond: liquid id {} at {:.4?} v {:.4?}", s.liquid.id[i], x, s.liquid.vel[i]);
                for k in 0..s.solid.len() {
                    let d = s.solid.pos[k] - x;
                    if d.length() < 1.6 * dx {
                        let memb = s.solid_extra.flags[k] & SolidFlags::MEMBRANE != 0;
                        let n0 = glam::Vec3::new(normal0[k][0] as f32, normal0[k][1] as f32, normal0[k][2] as f32);
                        let n = perfuse::sim::cpu::forces::capsule_normal(s.solid_extra.def_grad[k], n0);
                        eprintln!(
                            "   solid {k} d/dx {:+.2?} |d| {:.2} memb {memb} n {:+.2?} n0 {:+.2?} bonds {}/{} detF {:.2} (d·n)/dx {:+.2}",
                            d / dx,
                            d.length() / dx,
                            n,
                            n0,
                            s.solid_extra.bonds[k],
                            s.solid_extra.bonds_initial[k],
                            s.solid_extra.def_grad[k].determinant(),
                            -d.dot(n) / dx
                        );
                    }
                }
            }
        }
        last_beyond = beyond;
        if t >= t_end - 1e-9 {
            break;
        }
        t = (t + frame).min(t_end);
        sim.advance_until(t, u64::MAX, |_| {})?;
    }
    // the particles leaving at the end, traced back
    let (_, last, _, _) = frames.last().ok_or("no frame")?;
    let ids: Vec<usize> = match std::env::var("IDS") {
        Ok(s) => s.split(',').filter_map(|x| x.parse().ok()).collect(),
        Err(_) if std::env::var("BEYOND").is_ok() => {
            (0..last.len()).filter(|&i| last_beyond.contains(&last.id[i])).collect()
        }
        Err(_) => (0..last.len()).filter(|&i| last.n_s[i] < 0.12).collect(),
    };
    println!("dx {dx}; {} leaving at the end", ids.len());
    for &i in ids.iter().take(40) {
        println!("liquid id {}", last.id[i]);
        for (ft, l, s, flags) in &frames {
            let xi = l.pos[i];
            // nearest membrane particle, local outward normal from the solid's centre of mass near it
            let mut best = (f32::MAX, 0usize);
            for k in 0..s.len() {
                if flags[k] & SolidFlags::MEMBRANE != 0 {
                    let d = s.pos[k].distance(xi);
                    if d < best.0 {
                        best = (d, k);
                    }
                }
            }
            let xm = s.pos[best.1];
            let (mut com, mut n) = (glam::Vec3::ZERO, 0.0);
            let mut mem_near = 0;
            let mut gap = f32::MAX;
            for k in 0..s.len() {
                let d = s.pos[k].distance(xm);
                if d < 2.0 * dx {
                    com += s.pos[k];
                    n += 1.0;
                }
            }
            let nrm = (xm - com / n).normalize_or_zero();
            let sd = (xi - xm).dot(nrm);
            for k in 0..s.len() {
                if flags[k] & SolidFlags::MEMBRANE != 0 {
                    let d = s.pos[k] - xi;
                    if d.length() < 1.5 * dx {
                        mem_near += 1;
                        let tang = d - nrm * d.dot(nrm);
                        if d.dot(nrm).abs() < 0.5 * dx {
                            gap = gap.min(tang.length());
                        }
                    }
                }
            }
            // solid particles (any) within dx
            let solid_near = s.pos.iter().filter(|p| p.distance(xi) < dx).count();
            println!(
                "  t {:.3} x ({:+.4} {:+.4} {:+.4}) v ({:+.4} {:+.4} {:+.4}) ns {:.3} nl {:.3} p {:8.1} | memb d {:.2}dx sd {:+.2}dx n̂ ({:+.2} {:+.2} {:+.2}) within1.5dx {} tangential gap {:.2}dx solid<dx {}",
                ft,
                xi.x,
                xi.y,
                xi.z,
                l.vel[i].x,
                l.vel[i].y,
                l.vel[i].z,
                l.n_s[i],
                l.n_l[i],
                l.p[i],
                best.0 / dx,
                sd / dx,
                nrm.x,
                nrm.y,
                nrm.z,
                mem_near,
                gap / dx,
                solid_near
            );
        }
    }
    Ok(())
}
