//! The oscillating-wall tank (SPEC §7.13, `assets/scenarios/oscillating_wall.ron`) must be leak-proof by
//! construction: at every phase of the wall's motion the walls and the floor form one closed layer of
//! virtual particles at least 3Δx ≥ R thick, with no slot between the floor and a wall (an earlier layout
//! with box edges rounded to four digits lost one layer per object and opened a 1.5Δx slot at both bottom
//! corners through which half of the liquid drained).

use perfuse::scenario::Scenario;
use perfuse::sim::{BackendKind, Command, Simulation};
use std::path::Path;

/// Largest distance from a point of the 3Δx-thick wall/floor slab to its nearest boundary particle; a
/// complete square lattice of spacing Δx gives Δx/√2.
fn largest_hole(bnd: &[[f64; 2]], x_wall: f64, dx: f64) -> (f64, [f64; 2]) {
    let (w, depth, height) = (1.0, 3.0 * dx, 1.0);
    let n = 4.0;
    let mut samples = Vec::new();
    let mut slab = |x0: f64, x1: f64, y0: f64, y1: f64| {
        let (nx, ny) = (((x1 - x0) / dx * n).round() as i32, ((y1 - y0) / dx * n).round() as i32);
        for i in 0..=nx {
            for j in 0..=ny {
                samples.push([
                    x0 + (x1 - x0) * f64::from(i) / f64::from(nx),
                    y0 + (y1 - y0) * f64::from(j) / f64::from(ny),
                ]);
            }
        }
    };
    slab(x_wall - depth, w + depth, -depth, 0.0); // floor, under both walls
    slab(x_wall - depth, x_wall, 0.0, height); // moving left wall
    slab(w, w + depth, 0.0, height); // right wall
    let mut worst = (0.0, [0.0; 2]);
    for s in samples {
        let d = bnd.iter().map(|b| (b[0] - s[0]).hypot(b[1] - s[1])).fold(f64::INFINITY, f64::min);
        if d > worst.0 {
            worst = (d, s);
        }
    }
    worst
}

#[test]
fn oscillating_wall_tank_is_closed_at_every_wall_phase() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/oscillating_wall.ron");
    let sc = Scenario::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let dx = sc.numerics.dx_liquid.expect("dx_liquid");
    let mut sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    let st = sim.read_state().expect("state");
    assert_eq!(st.liquid.len(), 1980, "thesis §5.3.1: 1980 particles");
    let to_xy = |sim: &Simulation, p: glam::Vec3| {
        let w = sim.params().to_world(p);
        [w[0], w[1]]
    };
    // The liquid starts on the walls' lattice, one Δx from the nearest boundary particle.
    let bnd: Vec<[f64; 2]> = st.boundary.pos.iter().map(|&p| to_xy(&sim, p)).collect();
    for &p in &st.liquid.pos {
        let x = to_xy(&sim, p);
        let d = bnd.iter().map(|b| (b[0] - x[0]).hypot(b[1] - x[1])).fold(f64::INFINITY, f64::min);
        assert!(d > 0.999 * dx, "liquid particle at {x:?} is {:.3}Δx from a wall particle", d / dx);
    }
    // A period of the wall (f = 0.5 Hz) in 16 phases: x_w = (W/4) sin(πt).
    for k in 0..16 {
        let t = 0.125 * f64::from(k);
        sim.apply(&Command::SetTime(t)).expect("set time");
        let st = sim.read_state().expect("state");
        let bnd: Vec<[f64; 2]> = st.boundary.pos.iter().map(|&p| to_xy(&sim, p)).collect();
        let x_wall = 0.25 * (std::f64::consts::PI * t).sin();
        let (hole, at) = largest_hole(&bnd, x_wall, dx);
        assert!(
            hole <= 0.72 * dx,
            "t = {t} s (wall at {x_wall:.4} m): a point of the wall layer at {at:?} is {:.3}Δx from the nearest \
             boundary particle (a closed lattice gives 0.707Δx)",
            hole / dx
        );
    }
}
