//! Small scenes for the differential tests: seconds on lavapipe.

use perfuse::scenario::Scenario;

/// A 3-D perfused block (8×8×5 solid + 8×8×5 liquid at Δx = 0.5 mm) on a wall, its bottom layer
/// clamped, pressed by a descending spherical tool (640 particles, 432 + ~17 boundary particles).
pub const PERFUSED_BLOCK_3D: &str = r#"
Scenario(
    name: "gpu_test_block",
    dimensions: 3,
    domain: Domain(min: (0.0, 0.0, 0.0), max: (0.006, 0.006, 0.006)),
    gravity: (0.0, 0.0, -9.81),
    liquid: Some(Liquid(density: 1000.0, viscosity: 0.01, sound_speed: Some(2.0))),
    solid: Some(Solid(density: 1000.0, c10: 1000.0, c01: 100.0, k_s: 10000.0, n_sat: 0.5, k_sat: 1000.0, friction: 10000.0)),
    numerics: Numerics(dx_liquid: Some(5.0e-4), dx_solid: Some(5.0e-4), h_over_dx: 1.3),
    particles: [ PerfusedBlock(min: (0.001, 0.001, 0.0015), max: (0.005, 0.005, 0.004), solid_fraction: 0.5, liquid_fraction: 0.5) ],
    boundaries: [
        Boundary(name: "floor", shape: Box(min: (0.0, 0.0, 0.0), max: (0.006, 0.006, 0.0015))),
        Boundary(name: "tool", shape: Sphere(centre: (0.003, 0.003, 0.005), radius: 0.0008),
                 motion: Translate(velocity: (0.0, 0.0, -0.1))),
    ],
    fixed_regions: [ Box(min: (-1.0, -1.0, -1.0), max: (1.0, 1.0, 0.002)) ],
    duration: 0.01,
)
"#;

pub fn perfused_block() -> Scenario {
    Scenario::from_str_named(PERFUSED_BLOCK_3D, "gpu_test_block.ron").expect("test scene is valid")
}

/// [`PERFUSED_BLOCK_3D`] with the tool oscillating vertically instead of descending.
pub fn perfused_block_oscillating() -> Scenario {
    let text = PERFUSED_BLOCK_3D.replace(
        "motion: Translate(velocity: (0.0, 0.0, -0.1))",
        "motion: Oscillate(amplitude: (0.0, 0.0, -0.0006), frequency: 100.0, phase: 0.3)",
    );
    assert_ne!(text, PERFUSED_BLOCK_3D, "the tool's motion was replaced");
    Scenario::from_str_named(&text, "gpu_test_block_osc.ron").expect("test scene is valid")
}

/// Surface tension on both back-ends (SPEC §3.12): a 3-D liquid box standing on a plate, a fabric sheet
/// (Δx_s = 0.25 mm, nˢ = 0.3, half of it held) lying on the liquid's top, liquid–void attraction (3.4),
/// cohesion and adhesion (3.3), and C₁ from nˡ_eq = 0.5 (3.5). About 500 liquid, 400 fabric particles.
pub fn wicking_block() -> Scenario {
    let text = r#"Scenario(
        name: "gpu_test_wicking", dimensions: 3,
        domain: Domain(min: (0.0, 0.0, 0.0), max: (0.006, 0.006, 0.006)),
        gravity: (0.0, 0.0, -9.81),
        liquid: Some(Liquid(density: 1000.0, viscosity: 0.35, sound_speed: Some(2.0),
            c1_from_equilibrium: Some(Equilibrium(solid_fraction: 0.3, liquid_fraction: 0.5)),
            wicking: 0.0728, cohesion: Some(Cohesion(liquid: 2e-6, boundary: 1e-6)))),
        solid: Some(Solid(density: 1000.0, c10: 100.0, c01: 0.0, k_s: 1000.0, n_sat: 0.3, k_sat: 0.0,
            friction: 3.5e5)),
        numerics: Numerics(dx_liquid: Some(5.0e-4), dx_solid: Some(2.5e-4), h_over_dx: 1.3, liquid_tension: true,
            liquid_artificial_pressure: Some(ArtificialStress(epsilon: 0.2, exponent: 4))),
        particles: [
            Box(phase: Liquid, min: (0.001, 0.001, 0.0015), max: (0.005, 0.005, 0.0030), fraction: 1.0),
            Sheet(centre: (0.003, 0.003, 0.0031), size: (0.005, 0.005), fraction: 0.3),
        ],
        boundaries: [ Boundary(name: "plate", shape: Box(min: (0.0, 0.0, 0.0), max: (0.006, 0.006, 0.0015)),
                               spacing: Some(5.0e-4)) ],
        fixed_regions: [ Box(min: (-1.0, -1.0, -1.0), max: (0.003, 1.0, 1.0)) ],
        duration: 0.01,
    )"#;
    Scenario::from_str_named(text, "gpu_test_wicking.ron").expect("test scene is valid")
}

/// The 2-D start-up Poiseuille channel (periodic in x) re-gridded to 20 rows × 10 columns (Δx = 1 mm)
/// by `analysis::validate`'s own channel overrides.
pub fn poiseuille_small() -> Scenario {
    let ov = perfuse::analysis::validate::channel_overrides(20, 10, false);
    let text = include_str!("../../assets/scenarios/poiseuille.ron");
    Scenario::from_str_with_overrides(text, "assets/scenarios/poiseuille.ron", &ov).expect("test scene is valid")
}

/// A 2-D solid slab clamped at both ends, torn by a ball driven through it (Alg. 2), optionally with
/// a critical stretch λ_c.
pub fn tear(critical_stretch: Option<f64>) -> Scenario {
    let stretch = critical_stretch.map(|l| format!(", critical_stretch: Some({l})")).unwrap_or_default();
    let text = format!(
        r#"Scenario(
        name: "tear", dimensions: 2,
        domain: Domain(min: (-0.05, -0.05, 0.0), max: (0.05, 0.05, 0.0)),
        solid: Some(Solid(density: 1000.0, c10: 2e4, c01: 0.0, k_s: 1e5, n_sat: 1.0, k_sat: 0.0{stretch})),
        numerics: Numerics(dx_solid: Some(0.002)),
        particles: [ Box(phase: Solid, min: (-0.02, -0.01, 0.0), max: (0.02, 0.01, 0.0), fraction: 1.0) ],
        fixed_regions: [ Box(min: (-0.03, -0.02, -1.0), max: (-0.017, 0.02, 1.0)), Box(min: (0.017, -0.02, -1.0), max: (0.03, 0.02, 1.0)) ],
        boundaries: [ Boundary(name: "ball", shape: Sphere(centre: (0.0, 0.02, 0.0), radius: 0.004), spacing: Some(0.001),
                               motion: Translate(velocity: (0.0, -4.0, 0.0))) ],
        duration: 0.012,
    )"#
    );
    Scenario::from_str_named(&text, "tear.ron").expect("valid")
}

/// A 2-D block of tissue 6 cm × 3 cm (Δx = 3 mm, 200 particles) clamped by its left end over a plate,
/// cut at x = 3 mm (between two lattice columns) by a scalpel (a 3 mm thin box, two layers at Δx/2)
/// coming down at 1 m/s — the hanging liver of thesis §4.2.6 in miniature — with the thesis criterion
/// only or also `blade_cut` (SPEC §4.6).
pub fn hanging_cut(blade_cut: bool) -> Scenario {
    let text = format!(
        r#"Scenario(
        name: "hanging_cut", dimensions: 2,
        domain: Domain(min: (-0.05, -0.07, 0.0), max: (0.05, 0.07, 0.0)),
        gravity: (0.0, -9.81, 0.0),
        solid: Some(Solid(density: 1000.0, c10: 1e5, c01: 0.0, k_s: 1e5, n_sat: 1.0, k_sat: 0.0)),
        numerics: Numerics(dx_solid: Some(0.003)),
        particles: [ Box(phase: Solid, min: (-0.03, -0.015, 0.0), max: (0.03, 0.015, 0.0), fraction: 1.0) ],
        fixed_regions: [ Box(min: (-0.04, -0.02, -1.0), max: (-0.021, 0.02, 1.0)) ],
        boundaries: [
            Boundary(name: "plate", shape: Box(min: (-0.045, -0.055, 0.0), max: (0.045, -0.046, 0.0))),
            Boundary(name: "scalpel", shape: Box(min: (0.0015, 0.025, 0.0), max: (0.0045, 0.055, 0.0)), spacing: Some(0.0015),
                     motion: Translate(velocity: (0.0, -1.0, 0.0), start: 0.0, stop: Some(0.048)),
                     tool: Some(Tool(kind: Scalpel, max_speed: 1.0, blade_cut: {blade_cut}))),
        ],
        duration: 0.16,
    )"#
    );
    Scenario::from_str_named(&text, "hanging_cut.ron").expect("valid")
}

/// A 3-D tissue block 16 × 16 × 8 mm (Δx_s = 2 mm, 256 particles) resting on a plate with Coulomb
/// contact `Some(μ)` or SPEC §4.1's contact (`None`), with initial velocity `v0` along +x and gravity
/// `gravity` (tilt it for an inclined plane): the textbook sliding block (README: deviations from SPEC).
pub fn sliding_block(mu: Option<f64>, v0: f64, gravity: [f64; 3]) -> Scenario {
    let [gx, gy, gz] = gravity;
    let friction = mu.map(|m| format!("friction: Some({m:?}),")).unwrap_or_default();
    let text = format!(
        r#"Scenario(
        name: "sliding_block", dimensions: 3,
        domain: Domain(min: (-0.05, -0.02, -0.01), max: (0.05, 0.02, 0.03)),
        gravity: ({gx:?}, {gy:?}, {gz:?}),
        solid: Some(Solid(density: 1000.0, c10: 2e4, c01: 0.0, k_s: 1e5, n_sat: 1.0, k_sat: 0.0)),
        numerics: Numerics(dx_solid: Some(0.002)),
        particles: [ Box(phase: Solid, min: (-0.024, -0.008, 0.0), max: (-0.008, 0.008, 0.008), fraction: 1.0,
                         velocity: Some(Uniform(({v0:?}, 0.0, 0.0)))) ],
        boundaries: [ Boundary(name: "plate", shape: Box(min: (-0.045, -0.016, -0.006), max: (0.045, 0.016, 0.0)),
                               {friction}) ],
        duration: 0.1,
    )"#
    );
    Scenario::from_str_named(&text, "sliding_block.ron").expect("test scene is valid")
}

/// A 2-cm perfused cube (Δx = 4 mm, nˢ/nˡ = 0.6/0.4) at z ∈ [0, 2 cm] under gravity −z, nothing else
/// but the scenario entries in `extra` (a bed, ligaments): 0.1 s, roomy domain.
pub fn perfused_cube_under_gravity(name: &str, extra: &str) -> Scenario {
    let text = format!(
        r#"Scenario(
        name: "{name}", dimensions: 3,
        domain: Domain(min: (-0.03, -0.03, -0.03), max: (0.03, 0.03, 0.04)),
        gravity: (0.0, 0.0, -9.81),
        liquid: Some(Liquid(density: 1000.0, viscosity: 0.01, stiffness: Some(1e4))),
        solid: Some(Solid(density: 1000.0, c10: 1e3, c01: 0.0, k_s: 1e4, n_sat: 0.6, k_sat: 1e4, friction: 1e5)),
        numerics: Numerics(dx_solid: Some(0.004), dx_liquid: Some(0.004)),
        particles: [ PerfusedBlock(min: (-0.01, -0.01, 0.0), max: (0.01, 0.01, 0.02), solid_fraction: 0.6, liquid_fraction: 0.4) ],
        {extra}
        duration: 0.1,
    )"#
    );
    Scenario::from_str_named(&text, &format!("{name}.ron")).expect("test scene is valid")
}
