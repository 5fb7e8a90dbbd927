//! Diagnostic: relax a scenario (as `perfuse run` does) and describe the fastest solid particles at
//! t = 0 — kind (membrane or not, fixed), position, speed, bonds — and the bonds broken while relaxing.
//! Found the projectile specimen's relaxed max |v| (README: the projectile case).
//!
//! ```text
//! cargo run --release --example relax_probe -- SCENARIO [k=v]...
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
    sim.relax(|_| {})?;
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
    let lspeed: Vec<f32> = s.liquid.vel.iter().map(|v| v.length()).collect();
    println!(
        "liquid: mean speed {:.2} mm/s, max {:.2} mm/s, outside (nˢ < 0.05) {}",
        lspeed.iter().sum::<f32>() / lspeed.len().max(1) as f32 * 1e3,
        lspeed.iter().copied().fold(0.0, f32::max) * 1e3,
        s.liquid_outside()
    );
    Ok(())
}
