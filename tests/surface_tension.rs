//! Surface tension and wicking (thesis §3.2, eqs. 3.3–3.5; SPEC §3.12, §7.12) on the CPU reference
//! solver; the GPU twin of the same force terms is differential-tested in `gpu_vs_cpu.rs`.

use perfuse::analysis::wetting::{self, ContactAngle};
use perfuse::scenario::Scenario;
use perfuse::sim::{BackendKind, Simulation};

const DX: f64 = 1e-4;

/// A 2-D drop (R = 0.8 mm, Δx_l = 0.1 mm, 197 particles) touching a plate, with cohesion s_ll (3.3)
/// and adhesion s_lb to the plate; no gravity, so that the cap is shaped by (3.3) alone (at this
/// strength a 1 mm drop under gravity slumps into a puddle: Bond number ≈ 3).
fn drop_on_plate(adhesion: f64) -> Scenario {
    let text = format!(
        r#"Scenario(
        name: "drop_on_plate", dimensions: 2,
        domain: Domain(min: (-0.003, -0.0006, 0.0), max: (0.003, 0.004, 0.0)),
        gravity: (0.0, 0.0, 0.0),
        liquid: Some(Liquid(density: 1000.0, viscosity: 0.05, sound_speed: Some(4.0),
            cohesion: Some(Cohesion(liquid: 0.002, boundary: {adhesion})))),
        numerics: Numerics(dx_liquid: Some(1.0e-4), h_over_dx: 1.3),
        particles: [ Sphere(phase: Liquid, centre: (0.0, 0.00085, 0.0), radius: 0.0008, fraction: 1.0) ],
        boundaries: [ Boundary(name: "plate", shape: Box(min: (-0.0025, -0.0004, 0.0), max: (0.0025, 0.0, 0.0))) ],
        duration: 0.1,
    )"#
    );
    Scenario::from_str_named(&text, "drop_on_plate.ron").expect("test scene is valid")
}

/// Runs the drop to `until` and returns the contact angle at `samples` times.
fn contact_angles(adhesion: f64, samples: &[f64]) -> Vec<ContactAngle> {
    let sc = drop_on_plate(adhesion);
    let mut sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    let mass0 = sim.read_state().expect("state").liquid.total_mass();
    let plate_top = sim.params().to_sim([0.0, 0.0, 0.0]).y as f64;
    let mut out = Vec::new();
    for &t in samples {
        sim.advance_until(t, u64::MAX, |_| {}).expect("run");
        let s = sim.read_state().expect("state");
        assert!(s.liquid.pos.iter().all(|p| p.is_finite()), "finite positions");
        assert!((s.liquid.total_mass() - mass0).abs() <= 1e-9 * mass0, "mass conserved");
        // No penetration (SPEC §7.5 invariant): every liquid particle ≥ 0.3Δx from the plate's top row of
        // particles at −Δx/2, i.e. above −0.2Δx. Adhesion pulls the contact layer down to the surface.
        let lowest = s.liquid.pos.iter().map(|p| p.y as f64).fold(f64::INFINITY, f64::min);
        assert!(lowest > plate_top - 0.2 * DX, "liquid entered the plate: lowest particle {lowest:.3e} m");
        // The drop's volume: its particle count times the lattice cell (the liquid stays within ~1 % of ρ₀).
        let volume = s.liquid.len() as f64 * DX * DX;
        out.push(wetting::contact_angle(&s.liquid.pos, volume, plate_top, DX, 2, 1).expect("a cap on the plate"));
    }
    out
}

/// A drop on an impermeable plate (thesis Fig. 3.13): with cohesion s_ll and adhesion s_lb of (3.3) it
/// settles into a steady cap whose contact angle falls as the adhesion grows (Young: cos θ rises with the
/// liquid–plate attraction). Measured over 120–200 ms (five samples; θ jitters by ±5° at the particle
/// scale of this 197-particle drop): each cap steady (samples within a 12° band) and the mean angles
/// falling with s_lb/s_ll = 0.75, 1.0, 1.5, each step by more than 3°. Measured on this drop (README):
/// ≈ 91°, 84°, 75°. The cap is still spreading before ≈ 100 ms, and how it gets there depends on the
/// order of the neighbour sums (the contact line sticks and slips on the plate's particle lattice): at
/// 0.75, 60–100 ms read 108° → 92° with the 5³ neighbour block, 107° → 96° with the former 3³ one, but
/// 120–200 ms agree within the jitter for 3³, 5³ and 7³ blocks (≈ 91–96°, 84–89°, 72–77°). Weaker
/// adhesion is not steady within the test's time (at 0.5 the cap keeps rising past 125°, at 0.25 the
/// drop lets go of the plate).
#[test]
fn drop_contact_angle_falls_as_adhesion_grows() {
    let ratios = [0.75, 1.0, 1.5];
    let mut theta = Vec::new();
    for r in ratios {
        let ca = contact_angles(0.002 * r, &[0.12, 0.14, 0.16, 0.18, 0.2]);
        let deg: Vec<f64> = ca.iter().map(|c| c.degrees).collect();
        let mean = deg.iter().sum::<f64>() / deg.len() as f64;
        let band = deg.iter().copied().fold(f64::MIN, f64::max) - deg.iter().copied().fold(f64::MAX, f64::min);
        eprintln!(
            "s_lb/s_ll = {r}: θ = {mean:.1}° (samples {deg:.1?}; from the contact layer {:.1}°), height {:.3} mm, \
             contact layer {:.3} mm half-width",
            ca[4].degrees_from_base,
            ca[4].height * 1e3,
            ca[4].base_half_width * 1e3
        );
        assert!(band < 12.0, "s_lb/s_ll = {r}: cap not steady ({deg:.1?})");
        theta.push(mean);
    }
    for w in theta.windows(2) {
        assert!(w[1] < w[0] - 3.0, "contact angle must fall with adhesion: {theta:.1?}");
    }
}

/// The fabric sheet's particle mass (SPEC §7.12: m_f = nˢ_f ρ₀ˢ/Σ_sheet W6(·; R_×)) makes a liquid
/// particle on the mid-plane see nˢ = nˢ_f, between sheet particles as on top of one (within 2 %: the
/// in-plane lattice sum varies with the offset), in 3-D and 2-D.
#[test]
fn sheet_shows_its_fraction_on_the_mid_plane() {
    for (dims, offset) in [(3, 0.0), (3, 0.5), (2, 0.0), (2, 0.5)] {
        let dx = 2.6e-4;
        let (domain, sheet, centre) = if dims == 3 {
            (
                "(-0.01, -0.01, -0.002), max: (0.01, 0.01, 0.002)",
                "(0.0, 0.0, 0.0), size: (0.0104, 0.0104)",
                (0.5 + offset, 0.5, 0.0),
            )
        } else {
            (
                "(-0.01, -0.002, 0.0), max: (0.01, 0.002, 0.0)",
                "(0.0, 0.0, 0.0), size: (0.0104, 0.0)",
                (0.5 + offset, 0.0, 0.0),
            )
        };
        let text = format!(
            r#"Scenario(
            name: "sheet", dimensions: {dims},
            domain: Domain(min: {domain}),
            liquid: Some(Liquid(density: 1000.0, viscosity: 0.35, sound_speed: Some(2.0))),
            solid: Some(Solid(density: 1200.0, c10: 1e3, c01: 0.0, k_s: 1e4, n_sat: 0.3, k_sat: 0.0)),
            numerics: Numerics(dx_liquid: Some(2.4e-4), dx_solid: Some({dx}), h_over_dx: 1.3),
            particles: [
                Sphere(phase: Liquid, centre: ({}, {}, {}), radius: 1e-6, fraction: 1.0),
                Sheet(centre: {sheet}, fraction: 0.3),
            ],
            fixed_regions: [ Box(min: (-1.0, -1.0, -1.0), max: (1.0, 1.0, 1.0)) ],
            duration: 0.01,
        )"#,
            centre.0 * dx,
            centre.1 * dx,
            centre.2 * dx
        );
        let sc = Scenario::from_str_named(&text, "sheet.ron").expect("valid");
        let mut sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
        sim.step().expect("step");
        let s = sim.read_state().expect("state");
        assert_eq!(s.liquid.len(), 1);
        let ns = s.liquid.n_s[0];
        eprintln!("{dims}-D, offset {offset}Δx: nˢ = {ns:.4}");
        assert!((ns - 0.3).abs() < 0.02 * 0.3, "{dims}-D sheet shows nˢ = {ns}");
    }
}

/// The shipped fabric scenario `file` at the reduced resolution of SPEC §8.2 (W1–W3): fabric particles at
/// 5Δx_s = 0.26 mm and a 1021-particle drop (Δx_l = 0.2419 mm) of the same 15 µL; the sheet cut to its
/// central 60 × 60 particles (15.6 mm: the stain stays within 6 mm of the centre over the test's 30 ms).
fn fabric(file: &str) -> Scenario {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios").join(file);
    let set = [
        "numerics.dx_solid=0.00026".to_string(),
        "numerics.dx_liquid=0.00024191".to_string(),
        "particles.1.size=[0.0156,0.0156]".to_string(),
    ];
    Scenario::load_with_overrides(&path, &set).unwrap_or_else(|e| panic!("{e}"))
}

struct Wicked {
    /// Fraction of the liquid within R_× of the sheet's plane.
    in_sheet: f64,
    stain: wetting::Stain,
    a_ref: f64,
    n_l_max: f32,
}

/// Runs a reduced fabric case to `t` and measures it (SPEC §7.12 "Measured").
fn wick(file: &str, n_eq: f64, t: f64) -> Wicked {
    let sc = fabric(file);
    let mut sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    let mass0 = sim.read_state().expect("state").liquid.total_mass();
    sim.advance_until(t, u64::MAX, |_| {}).expect("run");
    let p = sim.params().clone();
    let s = sim.read_state().expect("state");
    assert!(s.liquid.pos.iter().chain(&s.solid.pos).all(|x| x.is_finite()), "finite");
    assert!((s.liquid.total_mass() - mass0).abs() <= 1e-9 * mass0, "mass conserved");
    let r_x = p.k_cross.r as f64;
    // The sheet lies in the scenario's plane z = 0 (simulation coordinates are offset by the origin).
    let sheet_z = p.to_sim([0.0; 3]).z as f64;
    let in_sheet =
        s.liquid.pos.iter().filter(|x| (x.z as f64 - sheet_z).abs() < r_x).count() as f64 / s.liquid.len() as f64;
    let stain = wetting::stain(&s.solid.pos, &s.solid.n_l, n_eq, p.dx_solid as f64, 3);
    let volume = mass0 / p.rho0_l as f64;
    let a_ref = wetting::reference_stain_area(volume, n_eq, r_x, 3);
    let n_l_max = s.solid.n_l.iter().copied().fold(0.0, f32::max);
    eprintln!(
        "{file} at {t} s: {:.0} % of the liquid in the sheet, stain {:.1} mm² = {:.2} A_ref (A_ref {:.1} mm²), \
         centroid ({:.2}, {:.2}) mm, max nˡ on the fabric {n_l_max:.3}",
        100.0 * in_sheet,
        stain.area * 1e6,
        stain.area / a_ref,
        a_ref * 1e6,
        stain.centroid[0] * 1e3,
        stain.centroid[1] * 1e3
    );
    Wicked { in_sheet, stain, a_ref, n_l_max }
}

/// Wicking into a fabric (thesis §4.3; SPEC §7.12) at the reduced resolution, over the first 30 ms (the
/// 2 s runs of the acceptance, `perfuse validate --case wicking --quick`, take ≈ 15 min per case on two
/// cores). Checked: with γ = 0.0728 N/m (case 1) the attraction (3.4) draws ≥ 90 % of the drop into the
/// sheet within 30 ms, the stain is
/// centred (centroid within 1 mm) and the fabric never holds more than nˡ_eq + 0.05 (the pressure (3.5)
/// stops it at nˡ_eq); with γ ÷ 10 (case 3) less than half as much has entered by then. Mass is
/// conserved and every particle stays finite. The stain area is printed against A_ref.
#[test]
fn fabric_draws_the_drop_in_at_a_rate_set_by_the_attraction() {
    let strong = wick("fabric_spread.ron", 0.5, 0.03);
    let weak = wick("fabric_drip.ron", 0.15, 0.03);
    assert!(strong.in_sheet >= 0.9, "case 1: only {:.0} % in the sheet", 100.0 * strong.in_sheet);
    let c = strong.stain.centroid;
    assert!((c[0] * c[0] + c[1] * c[1]).sqrt() < 1e-3, "stain off-centre: {c:?}");
    assert!(strong.n_l_max <= 0.55, "fabric over-saturated: nˡ = {}", strong.n_l_max);
    assert!(strong.stain.area > 0.0 && strong.a_ref > 0.0);
    assert!(
        weak.in_sheet < 0.5 * strong.in_sheet,
        "γ ÷ 10 should wick slower: {:.2} vs {:.2}",
        weak.in_sheet,
        strong.in_sheet
    );
}

/// The liquid–void attraction (3.4) on a lone liquid particle above a dry fabric, against the equation
/// evaluated independently here in f64: a_i = (1/ρ_i) Σ_j w_j (γ/h_×²) cos(πr/(4h_×)) (x_j − x_i)/r with
/// w_j = 1 − nˢ_j − nˡ_j, nˡ_j = m_i W6(r; R_×)/ρ₀ˡ the fabric's summation of the one particle, and ρ_i
/// = m_i W6(0; R_l) its own. No gravity, no friction, no cohesion; the particle's pressure is clamped
/// at 0, so the attraction is its only force, read back as v/Δt after one step (within 10⁻⁴, f32).
#[test]
fn wicking_attraction_on_a_lone_particle_matches_eq_3_4() {
    let text = r#"Scenario(
        name: "lone", dimensions: 3,
        domain: Domain(min: (-0.004, -0.004, -0.002), max: (0.004, 0.004, 0.002)),
        liquid: Some(Liquid(density: 1000.0, viscosity: 0.0, sound_speed: Some(2.0), wicking: 0.0728)),
        solid: Some(Solid(density: 1000.0, c10: 1e3, c01: 0.0, k_s: 1e4, n_sat: 0.3, k_sat: 0.0)),
        numerics: Numerics(dx_liquid: Some(2.4191e-4), dx_solid: Some(2.6e-4), h_over_dx: 1.3),
        particles: [
            Sphere(phase: Liquid, centre: (0.0001, 0.00005, 0.0003), radius: 1e-6, fraction: 1.0),
            Sheet(centre: (0.0, 0.0, 0.0), size: (0.0052, 0.0052), fraction: 0.3),
        ],
        fixed_regions: [ Box(min: (-1.0, -1.0, -1.0), max: (1.0, 1.0, 1.0)) ],
        duration: 0.01,
    )"#;
    let sc = Scenario::from_str_named(text, "lone.ron").expect("valid");
    let mut sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    let s0 = sim.read_state().expect("state");
    let p = sim.params().clone();
    let (m, xi) = (s0.liquid.mass[0] as f64, s0.liquid.pos[0].as_dvec3());
    let pi = std::f64::consts::PI;
    let w6 = |r: f64, big_r: f64| {
        if r >= big_r { 0.0 } else { 315.0 / (64.0 * pi * big_r.powi(3)) * (1.0 - r * r / (big_r * big_r)).powi(3) }
    };
    let (h_x, r_l) = (p.k_cross.h as f64, p.k_liquid.r as f64);
    let rho_i = m * w6(0.0, r_l);
    let eq_3_4 = |xi: glam::DVec3| {
        let mut a = glam::DVec3::ZERO;
        for xj in &s0.solid.pos {
            let d = xj.as_dvec3() - xi;
            let r = d.length();
            if r < 2.0 * h_x && r > 0.0 {
                let n_l = m * w6(r, 2.0 * h_x) / p.rho0_l as f64;
                let w = (1.0 - 0.3 - n_l).max(0.0);
                a += d / r * (w * 0.0728 / (h_x * h_x) * (pi * r / (4.0 * h_x)).cos() / rho_i);
            }
        }
        a
    };
    sim.step().expect("step");
    let s1 = sim.read_state().expect("state");
    // Predictor–corrector (2.64)–(2.68): v¹ = ½Δt (a(x⁰) + a(x¹)).
    let a_ref = 0.5 * (eq_3_4(xi) + eq_3_4(s1.liquid.pos[0].as_dvec3()));
    let a = s1.liquid.vel[0].as_dvec3() / s1.t;
    eprintln!("attraction: solver {a:.4?} m/s², eq. (3.4) {a_ref:.4?} m/s²");
    assert!(a_ref.z < 0.0 && a_ref.length() > 1.0, "the reference pulls toward the sheet");
    assert!((a - a_ref).length() <= 1e-4 * a_ref.length(), "solver {a:?} vs (3.4) {a_ref:?}");
}

/// The pairwise surface tension (3.3) on two liquid particles next to one wall particle, against the
/// equation evaluated here: a_1 = (1/m)[s_ll cos(πr₁₂/(2R_l)) (x₂ − x₁)/r₁₂ + s_lb cos(πr₁b/(2R_l))
/// (x_b − x₁)/r₁b]. No gravity, no viscosity; both pressures are clamped at 0 (nˡ < 1), so (3.3) is the
/// only force; read back as v/Δt after one step (within 10⁻⁴).
#[test]
fn cohesion_and_adhesion_on_a_pair_match_eq_3_3() {
    let text = r#"Scenario(
        name: "pair", dimensions: 2,
        domain: Domain(min: (-0.002, -0.002, 0.0), max: (0.002, 0.002, 0.0)),
        liquid: Some(Liquid(density: 1000.0, viscosity: 0.0, sound_speed: Some(2.0),
            cohesion: Some(Cohesion(liquid: 0.002, boundary: 0.0015)))),
        numerics: Numerics(dx_liquid: Some(1.0e-4), h_over_dx: 1.3),
        particles: [
            Sphere(phase: Liquid, centre: (0.0, 0.0, 0.0), radius: 1e-7, fraction: 1.0),
            Sphere(phase: Liquid, centre: (0.00015, 0.00003, 0.0), radius: 1e-7, fraction: 1.0),
        ],
        boundaries: [ Boundary(name: "b", shape: Box(min: (-0.00005, -0.00025, 0.0), max: (0.00005, -0.00015, 0.0))) ],
        duration: 0.01,
    )"#;
    let sc = Scenario::from_str_named(text, "pair.ron").expect("valid");
    let mut sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    let s0 = sim.read_state().expect("state");
    assert_eq!((s0.liquid.len(), s0.boundary.pos.len()), (2, 1));
    let r_l = sim.params().k_liquid.r as f64;
    let m = s0.liquid.mass[0] as f64;
    let xb = s0.boundary.pos[0].as_dvec3();
    let pair = |s: f64, xi: glam::DVec3, xj: glam::DVec3| {
        let d = xj - xi;
        let r = d.length();
        if r < r_l { d / r * (s * (std::f64::consts::PI * r / (2.0 * r_l)).cos()) } else { glam::DVec3::ZERO }
    };
    let eq_3_3 = |x1: glam::DVec3, x2: glam::DVec3| (pair(0.002, x1, x2) + pair(0.0015, x1, xb)) / m;
    let x0 = (s0.liquid.pos[0].as_dvec3(), s0.liquid.pos[1].as_dvec3());
    sim.step().expect("step");
    let s1 = sim.read_state().expect("state");
    let x1 = (s1.liquid.pos[0].as_dvec3(), s1.liquid.pos[1].as_dvec3());
    let a_ref = 0.5 * (eq_3_3(x0.0, x0.1) + eq_3_3(x1.0, x1.1));
    let a = s1.liquid.vel[0].as_dvec3() / s1.t;
    eprintln!("surface tension: solver {a:.4?} m/s², eq. (3.3) {a_ref:.4?} m/s²");
    assert!(a_ref.length() > 1.0);
    assert!((a - a_ref).length() <= 1e-4 * a_ref.length(), "solver {a:?} vs (3.3) {a_ref:?}");
}

/// The liquid's artificial pressure (`numerics.liquid_artificial_pressure`; README: deviations from
/// SPEC) on a lone pair under tension (2-D, both pˡ = k(nˡ − 1) < 0, no viscosity, no gravity), at
/// r = ½Δx_l and r = 1.5Δx_l. Checked against the term evaluated here in f64: the acceleration it adds
/// to particle 0 is −½(n₀ + n₁) m (R₀ + R₁) f^n κ_S ∇W_S with R = ε|p|/ρ² and f = W_C(r; h)/W_C(Δx; h),
/// W_C written out from (2.29) (the spiky gradient is the solver's, tested in `kernels`); read back as
/// v/Δt after one step of Δt = 10⁻⁸ s (within 10⁻³ of it). At ½Δx_l the pair that tension pulls
/// together is pushed apart with the term, at 1.5Δx_l it still attracts (the term is short-ranged).
#[test]
fn artificial_pressure_repels_a_close_pair_under_tension() {
    let dx = 1.0e-4;
    let run = |sep: f64, eps: Option<f64>| {
        let ap = eps.map(|e| format!("liquid_artificial_pressure: Some(ArtificialStress(epsilon: {e}, exponent: 4)),"));
        let text = format!(
            r#"Scenario(
            name: "ap_pair", dimensions: 2,
            domain: Domain(min: (-0.002, -0.002, 0.0), max: (0.002, 0.002, 0.0)),
            liquid: Some(Liquid(density: 1000.0, viscosity: 0.0, sound_speed: Some(2.0))),
            numerics: Numerics(dx_liquid: Some({dx}), h_over_dx: 1.3, liquid_tension: true, fixed_dt: Some(1e-8),
                {}),
            particles: [
                Sphere(phase: Liquid, centre: (0.0, 0.0, 0.0), radius: 1e-7, fraction: 1.0),
                Sphere(phase: Liquid, centre: ({sep}, 0.0, 0.0), radius: 1e-7, fraction: 1.0),
            ],
            duration: 0.01,
        )"#,
            ap.unwrap_or_default()
        );
        let sc = Scenario::from_str_named(&text, "ap_pair.ron").expect("valid");
        let mut sim = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
        sim.step().expect("step");
        let s = sim.read_state().expect("state");
        assert_eq!(s.liquid.len(), 2);
        (s.liquid.vel[0].x as f64 / s.t, s, sim.params().clone())
    };
    for sep in [0.5 * dx, 1.5 * dx] {
        let (a_off, _, _) = run(sep, None);
        let (a_on, s, p) = run(sep, Some(0.2));
        let r = (s.liquid.pos[1] - s.liquid.pos[0]).length() as f64;
        let h = p.k_liquid.h as f64;
        let w_c = |r: f64| {
            let q = r / h;
            let a = 10.0 / (7.0 * std::f64::consts::PI * h * h);
            if q < 1.0 {
                a * (1.0 - 1.5 * q * q + 0.75 * q.powi(3))
            } else if q < 2.0 {
                a * 0.25 * (2.0 - q).powi(3)
            } else {
                0.0
            }
        };
        let (m, rho, pr, n_l) =
            (s.liquid.mass[0] as f64, s.liquid.rho[0] as f64, s.liquid.p[0] as f64, s.liquid.n_l[0] as f64);
        assert!(pr < 0.0, "the pair is under tension: p = {pr}");
        let big_r = 0.2 * 2.0 * (-pr) / (rho * rho);
        let f = w_c(r) / w_c(dx);
        // ∇W_S at x_0 − x_1 = (−r, 0): grad_spiky_factor × (−r)
        let grad_x = p.k_liquid.grad_spiky_factor(r as f32) as f64 * -r;
        let term = -n_l * m * big_r * f.powi(4) * p.kappa_s as f64 * grad_x;
        eprintln!(
            "r = {:.2}Δx: p = {pr:.1} Pa, a_x without {a_off:.4e}, with {a_on:.4e} m/s², term {:.4e} (reference {term:.4e})",
            r / dx,
            a_on - a_off
        );
        assert!(((a_on - a_off) - term).abs() <= 1e-3 * term.abs(), "term {} vs {term}", a_on - a_off);
        assert!(a_off > 0.0, "tension pulls particle 0 toward particle 1 (+x)");
        if sep < dx {
            assert!(a_on < 0.0, "with the term the close pair repels");
        } else {
            assert!(a_on > 0.0, "beyond Δx the term is small: the pair still attracts");
        }
    }
}
