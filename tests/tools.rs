//! Tool commands (the viewer's scalpel, indenter and projectile are kinematic boundary objects):
//! `PlaceObject` teleports an object's centre, `MoveObject` moves it at a bounded speed and stops at
//! the target, on both back-ends, with the same poses and the same particle state.

mod common;

use common::gpu::gpu_test;
use common::scenes::perfused_block;
use perfuse::scenario::Region;
use perfuse::sim::{BackendKind, Command, Simulation};

const TOOL: usize = 1;

fn centre(sim: &Simulation) -> [f64; 3] {
    sim.object_poses()[TOOL].centre
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Place above the block, move down 0.6 mm at 0.05 m/s (12 ms), run past the arrival: the tool sits
/// at the target and is at rest; returns the final state hash and the tool's boundary particles.
fn scripted(backend: BackendKind) -> (Simulation, u64) {
    let mut sim = Simulation::new(&perfused_block(), backend).expect("sim");
    let start = [0.0035, 0.003, 0.0052];
    sim.apply(&Command::PlaceObject { object: TOOL, position: start }).expect("place");
    assert!(dist(centre(&sim), start) < 1e-7, "placed at {:?}", centre(&sim));
    assert!(matches!(sim.object_poses()[TOOL].shape, Region::Sphere { .. }));
    let target = [0.0035, 0.003, 0.0046];
    sim.apply(&Command::MoveObject { object: TOOL, target, speed: 0.05 }).expect("move");
    let v = sim.object_poses()[TOOL].velocity;
    assert!((v[2] + 0.05).abs() < 1e-6 && v[0].abs() < 1e-6, "moving down at 0.05 m/s: {v:?}");
    sim.advance_until(0.02, 5000, |_| {}).expect("run");
    let c = centre(&sim);
    assert!(dist(c, target) < 1e-6, "arrived at {c:?}");
    assert_eq!(sim.object_poses()[TOOL].velocity, [0.0; 3], "at rest after arrival");
    // A non-finite or absurd command is refused with a message, the state untouched.
    let before = sim.read_state().expect("state").hash();
    let e = sim.apply(&Command::MoveObject { object: TOOL, target: [f64::NAN, 0.0, 0.0], speed: 1.0 });
    assert!(e.is_err_and(|e| e.to_string().contains("not finite")));
    let e = sim.apply(&Command::MoveObject { object: TOOL, target, speed: 0.0 });
    assert!(e.is_err_and(|e| e.to_string().contains("speed")));
    assert!(sim.apply(&Command::PlaceObject { object: 9, position: target }).is_err());
    assert_eq!(sim.read_state().expect("state").hash(), before);
    (sim, before)
}

#[test]
fn tool_commands_on_the_cpu() {
    let _ = scripted(BackendKind::Cpu);
}

#[test]
fn tool_commands_on_the_gpu_match_the_cpu() {
    gpu_test("tool_commands_on_the_gpu_match_the_cpu", |_ctx| {
        let (mut cpu, _) = scripted(BackendKind::Cpu);
        let (mut gpu, _) = scripted(BackendKind::Gpu);
        assert_eq!(cpu.object_poses(), gpu.object_poses());
        let (a, b) = (cpu.read_state().expect("cpu"), gpu.read_state().expect("gpu"));
        let h = cpu.params().k_solid.h;
        let worst = a
            .solid
            .pos
            .iter()
            .zip(&b.solid.pos)
            .chain(a.liquid.pos.iter().zip(&b.liquid.pos))
            .map(|(p, q)| (*p - *q).length())
            .fold(0.0f32, f32::max);
        assert!(worst <= 1e-3 * h, "positions differ by {worst} m (h = {h})");
        let bw = a.boundary.pos.iter().zip(&b.boundary.pos).map(|(p, q)| (*p - *q).length()).fold(0.0f32, f32::max);
        assert!(bw < 1e-7, "boundary particles differ by {bw} m");
    });
}
