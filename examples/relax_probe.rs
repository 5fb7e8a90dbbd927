//! Diagnostic: relax a scenario (as `perfuse run` does) and describe the fastest solid particles at
//! t = 0 — kind (membrane or not, fixed), position, speed, bonds — and the bonds broken while relaxing.
//! Found the projectile specimen's relaxed max |v| (README: the projectile case).
//!
//! `TRACE=Δt` also prints, every Δt seconds of the relaxation, the solid's largest and mean speed,
//! where the fastest particle is, the blood's mean speed and the blood beyond the capsule (counted as
//! the capsule case does, `analysis::capsule::liquid_beyond_capsule`): whether the motion decays at
//! the damping's rate or something keeps driving it (it showed the capsule seal's walk-back doing so;
//! README, Deviations); and the blood split by pressure, p ≤ 0 (the blood the seal walks back) or not,
//! with the fastest particle's place, pressure and fractions. `FASTLIQ=1` lists the eight fastest
//! particles at p ≤ 0 with their velocities (it found them pushed outward along the specimen's bottom
//! edges while their positions stay put).
//!
//! ```text
//! [TRACE=0.05 [FASTLIQ=1]] cargo run --release --example relax_probe -- SCENARIO [k=v]...
//! ```

use perfuse::scenario::{Scenario, SolidFlags};
use perfuse::sim::{BackendKind, Simulation};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 2 {
        return Err("usage: relax_probe SCENARIO [k=v]...".into());
    }
    let sets: Vec<String> = args[2..].iter().filter(|a| *a != "--set").cloned().collect();
    let sc = Scenario::load_with_overrides(Path::new(&args[1]), &sets)?;
    let mut sim = Simulation::new(&sc, BackendKind::Cpu)?;
    let t0 = std::time::Instant::now();
    match (std::env::var("TRACE").ok().and_then(|t| t.parse::<f64>().ok()), sc.relaxation.clone()) {
        // TRACE=Δt: the relaxation in steps of Δt [s], with the solid's largest and mean speed, the
        // fastest particle's kind and place, and the liquid's mean speed after each
        (Some(every), Some(r)) if every > 0.0 && r.duration > 0.0 => {
            for c in r.start_commands() {
                sim.apply(&c)?;
            }
            // positions in the scenario's coordinates (the state's are relative to `Params::origin`)
            let o = sim.params().origin;
            let origin = glam::Vec3::new(o[0] as f32, o[1] as f32, o[2] as f32);
            // blood beyond the capsule's local hull, as the capsule case counts it
            let normal0 = perfuse::scenario::generate(&sc).solid_normal;
            let dx_s = sim.params().dx_solid;
            let mut t = -r.duration;
            while t < -1e-12 {
                t = (t + every).min(0.0);
                sim.advance_until(t, u64::MAX, |_| {})?;
                let s = sim.read_state()?;
                let speed: Vec<f32> = s.solid.vel.iter().map(|v| v.length()).collect();
                let k = (0..speed.len()).max_by(|&a, &b| speed[a].total_cmp(&speed[b])).unwrap_or(0);
                let mean = speed.iter().sum::<f32>() / speed.len().max(1) as f32;
                let lmean = s.liquid.vel.iter().map(|v| v.length()).sum::<f32>() / s.liquid.len().max(1) as f32;
                println!(
                    "t {t:+.3} s: solid max {:.2} mm/s (#{k}, membrane {}, at {:+.4?}), mean {:.3} mm/s; liquid mean {:.2} mm/s, broken {}, beyond the capsule {}",
                    speed.get(k).copied().unwrap_or(0.0) * 1e3,
                    s.solid_extra.flags.get(k).is_some_and(|f| f & SolidFlags::MEMBRANE != 0),
                    s.solid.pos.get(k).copied().unwrap_or_default() + origin,
                    mean * 1e3,
                    lmean * 1e3,
                    s.broken_bonds(),
                    perfuse::analysis::capsule::liquid_beyond_capsule(&s, &normal0, dx_s)
                );
                // the blood by its pressure: unsaturated (p ≤ 0, what the seal's walk-back moves) or not
                let lspeed: Vec<f32> = s.liquid.vel.iter().map(|v| v.length()).collect();
                let (mut n0, mut s0, mut n1, mut s1) = (0usize, 0.0f32, 0usize, 0.0f32);
                for (v, p) in lspeed.iter().zip(&s.liquid.p) {
                    if *p <= 0.0 {
                        n0 += 1;
                        s0 += v;
                    } else {
                        n1 += 1;
                        s1 += v;
                    }
                }
                if std::env::var_os("FASTLIQ").is_some() {
                    let mut order: Vec<usize> = (0..lspeed.len()).filter(|&k| s.liquid.p[k] <= 0.0).collect();
                    order.sort_by(|&a, &b| lspeed[b].total_cmp(&lspeed[a]));
                    for &k in order.iter().take(8) {
                        println!(
                            "      p<=0 liquid {}: |v| {:.1} mm/s v {:+.1?} mm/s at {:+.4?} n_s {:.3} n_l {:.3}",
                            s.liquid.id[k],
                            lspeed[k] * 1e3,
                            s.liquid.vel[k] * 1e3,
                            s.liquid.pos[k] + origin,
                            s.liquid.n_s[k],
                            s.liquid.n_l[k]
                        );
                    }
                }
                let kl = (0..lspeed.len()).max_by(|&a, &b| lspeed[a].total_cmp(&lspeed[b])).unwrap_or(0);
                println!(
                    "    liquid at p <= 0: {n0}, mean {:.2} mm/s; at p > 0: {n1}, mean {:.2} mm/s; fastest {:.1} mm/s at {:+.4?}, p {:.1} Pa, n_s {:.3}, n_l {:.3}",
                    s0 / n0.max(1) as f32 * 1e3,
                    s1 / n1.max(1) as f32 * 1e3,
                    lspeed.get(kl).copied().unwrap_or(0.0) * 1e3,
                    s.liquid.pos.get(kl).copied().unwrap_or_default() + origin,
                    s.liquid.p.get(kl).copied().unwrap_or(0.0),
                    s.liquid.n_s.get(kl).copied().unwrap_or(0.0),
                    s.liquid.n_l.get(kl).copied().unwrap_or(0.0),
                );
            }
            for c in r.end_commands() {
                sim.apply(&c)?;
            }
        }
        _ => sim.relax(|_| {})?,
    }
    let s = sim.read_state()?;
    let n = s.solid.len();
    let speed: Vec<f32> = s.solid.vel.iter().map(|v| v.length()).collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| speed[b].total_cmp(&speed[a]));
    let memb = |k: usize| s.solid_extra.flags[k] & SolidFlags::MEMBRANE != 0;
    println!(
        "relaxed in {:.0} s: {n} solid ({} membrane), {} liquid; mean speed {:.2} mm/s, broken bonds {}",
        t0.elapsed().as_secs_f64(),
        (0..n).filter(|&k| memb(k)).count(),
        s.liquid.len(),
        speed.iter().sum::<f32>() / n.max(1) as f32 * 1e3,
        s.broken_bonds()
    );
    let mean_of = |want: bool| {
        let v: Vec<f32> = (0..n).filter(|&k| memb(k) == want).map(|k| speed[k]).collect();
        v.iter().sum::<f32>() / v.len().max(1) as f32 * 1e3
    };
    println!("  mean speed: capsule {:.2} mm/s, tissue {:.2} mm/s", mean_of(true), mean_of(false));
    for &k in order.iter().take(15) {
        println!(
            "  solid {k}: |v| {:.2} mm/s v {:+.2?} mm/s at {:+.4?} membrane {} flags {:#x} bonds {}/{}",
            speed[k] * 1e3,
            s.solid.vel[k] * 1e3,
            s.solid.pos[k],
            memb(k),
            s.solid_extra.flags[k],
            s.solid_extra.bonds[k],
            s.solid_extra.bonds_initial[k]
        );
    }
    if std::env::var_os("SEAL").is_some() {
        // SEAL=1: for the five fastest capsule particles, the capsule's normal cof(F)n̂₀ against its
        // initial n̂₀, and the blood within Δx_s: depth along the normal (the seal's band is ±Δx_l/4) and
        // the relative normal velocity (what the seal stops when outward)
        let normal0: Vec<glam::Vec3> = perfuse::scenario::generate(&sc)
            .solid_normal
            .iter()
            .map(|n| glam::Vec3::new(n[0] as f32, n[1] as f32, n[2] as f32))
            .collect();
        let (dx_s, dx_l) = (sim.params().dx_solid, sim.params().dx_liquid);
        for &k in order.iter().filter(|&&k| memb(k)).take(5) {
            let n = perfuse::sim::cpu::forces::capsule_normal(s.solid_extra.def_grad[k], normal0[k]);
            println!(
                "  capsule {k}: n {:+.2?} (n0 {:+.2?}, angle {:.0}°), v·n {:+.2} mm/s, v tangential {:.2} mm/s",
                n,
                normal0[k],
                n.dot(normal0[k]).clamp(-1.0, 1.0).acos().to_degrees(),
                s.solid.vel[k].dot(n) * 1e3,
                (s.solid.vel[k] - n * s.solid.vel[k].dot(n)).length() * 1e3
            );
            for (i, x) in s.liquid.pos.iter().enumerate() {
                let d = *x - s.solid.pos[k];
                if d.length() < dx_s {
                    let sd = d.dot(n) / dx_l;
                    let vrel = (s.liquid.vel[i] - s.solid.vel[k]).dot(n) * 1e3;
                    println!(
                        "    liquid {i}: r {:.2} Δx_s, depth {sd:+.2} Δx_l{}, (v_i − v_j)·n {vrel:+.2} mm/s, |v_i| {:.2} mm/s",
                        d.length() / dx_s,
                        if sd.abs() < 0.25 { " (in band)" } else { "" },
                        s.liquid.vel[i].length() * 1e3
                    );
                }
            }
        }
    }
    let lspeed: Vec<f32> = s.liquid.vel.iter().map(|v| v.length()).collect();
    println!(
        "liquid: mean speed {:.2} mm/s, max {:.2} mm/s, outside (nˢ < 0.05) {}",
        lspeed.iter().sum::<f32>() / lspeed.len().max(1) as f32 * 1e3,
        lspeed.iter().copied().fold(0.0, f32::max) * 1e3,
        s.liquid_outside()
    );
    Ok(())
}
