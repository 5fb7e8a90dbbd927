//! Malformed scenarios: each bad input gives a clear error naming the field (or line/column) and a
//! fix, and nothing panics (issue: core, "at least 15 distinct bad inputs").

use perfuse::scenario::{Scenario, ScenarioError};

/// A small valid 2-D scenario; each case edits one thing.
const BASE: &str = r#"
Scenario(
    name: "base",
    dimensions: 2,
    domain: Domain(min: (0.0, -0.0125, 0.0), max: (0.01, 0.0125, 0.0), periodic: (true, false, false)),
    gravity: (0.3675, 0.0, 0.0),
    liquid: Some(Liquid(density: 1000.0, viscosity: 0.35, sound_speed: Some(0.6))),
    numerics: Numerics(dx_liquid: Some(5.0e-4), h_over_dx: 1.3, dt_min: 1e-9, dt_max: 1e-3),
    particles: [ Box(phase: Liquid, min: (0.0, -0.01, 0.0), max: (0.01, 0.01, 0.0), fraction: 1.0) ],
    boundaries: [ Boundary(name: "top", shape: Box(min: (0.0, 0.01, 0.0), max: (0.01, 0.0115, 0.0))) ],
    duration: 0.1,
)
"#;

/// The error for `text` loaded as the file `path` (relative mesh paths resolve against its folder);
/// the message must name the file.
fn err_named(text: &str, path: &str) -> String {
    match Scenario::from_str_named(text, path) {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => {
            let msg = e.to_string();
            let file = std::path::Path::new(path).file_name().and_then(|f| f.to_str()).unwrap_or(path);
            assert!(msg.contains(file), "message must name the file: {msg}");
            msg
        }
    }
}

fn edit(from: &str, to: &str) -> String {
    assert!(BASE.contains(from), "test bug: `{from}` not in BASE");
    BASE.replacen(from, to, 1)
}

fn expect(text: &str, needles: &[&str]) {
    expect_named(text, "bad.ron", needles);
}

fn expect_named(text: &str, path: &str, needles: &[&str]) {
    let msg = err_named(text, path);
    for n in needles {
        assert!(msg.contains(n), "expected `{n}` in: {msg}");
    }
}

#[test]
fn base_is_valid() {
    Scenario::from_str_named(BASE, "base.ron").expect("base scenario must be valid");
}

#[test]
fn syntax_error_gives_line_and_column() {
    let e = Scenario::from_str_named(&edit("dimensions: 2,", "dimensions: 2"), "bad.ron").unwrap_err();
    match e {
        ScenarioError::Syntax { line, .. } => assert!(line >= 5, "line {line}"),
        other => panic!("wrong error: {other}"),
    }
}

#[test]
fn unknown_field() {
    expect(&edit("duration: 0.1,", "duration: 0.1, durration: 2.0,"), &["durration", "line", "spelling"]);
}

#[test]
fn missing_field() {
    expect(&edit("duration: 0.1,", ""), &["duration", "add the field"]);
}

#[test]
fn unknown_enum_variant() {
    expect(&edit("phase: Liquid", "phase: Gas"), &["Gas", "variant"]);
}

#[test]
fn bad_dimensions() {
    expect(&edit("dimensions: 2,", "dimensions: 4,"), &["dimensions", "2 or 3"]);
}

#[test]
fn nan_value() {
    expect(&edit("viscosity: 0.35", "viscosity: NaN"), &["liquid.viscosity", "finite"]);
}

#[test]
fn negative_density() {
    expect(&edit("density: 1000.0", "density: -1000.0"), &["liquid.density", "> 0"]);
}

#[test]
fn zero_h() {
    expect(&edit("h_over_dx: 1.3", "h_over_dx: 0.0"), &["numerics.h_over_dx", "1 ≤ h/Δx ≤ 2"]);
}

#[test]
fn negative_spacing() {
    expect(&edit("dx_liquid: Some(5.0e-4)", "dx_liquid: Some(-5.0e-4)"), &["numerics.dx_liquid", "> 0"]);
}

#[test]
fn spacing_larger_than_domain() {
    expect(&edit("dx_liquid: Some(5.0e-4)", "dx_liquid: Some(0.5)"), &["numerics.dx_liquid", "larger than the domain"]);
}

#[test]
fn inverted_domain() {
    expect(
        &edit("max: (0.01, 0.0125, 0.0), periodic", "max: (0.01, -0.02, 0.0), periodic"),
        &["domain.max[1]", "lower corner"],
    );
}

#[test]
fn generator_outside_domain() {
    expect(
        &edit("min: (0.0, -0.01, 0.0), max: (0.01, 0.01, 0.0)", "min: (0.0, -0.01, 0.0), max: (0.01, 0.05, 0.0)"),
        &["particles[0]", "outside the domain"],
    );
}

#[test]
fn zero_particles() {
    expect(
        &edit("min: (0.0, -0.01, 0.0), max: (0.01, 0.01, 0.0)", "min: (0.0, -0.01, 0.0), max: (0.01, -0.0099, 0.0)"),
        &["particles[0]", "zero particles"],
    );
}

#[test]
fn liquid_without_material() {
    expect(
        &edit("liquid: Some(Liquid(density: 1000.0, viscosity: 0.35, sound_speed: Some(0.6))),", ""),
        &["liquid", "no liquid material"],
    );
}

#[test]
fn contradictory_stiffness_and_sound_speed() {
    expect(
        &edit("sound_speed: Some(0.6)", "sound_speed: Some(0.6), stiffness: Some(360.0)"),
        &["liquid.stiffness", "contradictory"],
    );
}

#[test]
fn fraction_out_of_range() {
    expect(&edit("fraction: 1.0", "fraction: 1.5"), &["particles[0].fraction", "volume fraction"]);
}

#[test]
fn negative_mooney_rivlin() {
    let text = edit(
        "numerics:",
        "solid: Some(Solid(density: 1000.0, c10: -5.0, c01: 0.0, k_s: 1e5, n_sat: 0.6, k_sat: 1e5)),\n    numerics:",
    );
    expect(&text, &["solid.c10", "≥ 0"]);
}

#[test]
fn artificial_pressure_needs_tension_and_a_sane_exponent() {
    let ap = |body: &str| edit("dt_max: 1e-3", &format!("dt_max: 1e-3, {body}"));
    expect(
        &ap("liquid_artificial_pressure: Some(ArtificialStress(epsilon: 0.2))"),
        &["numerics.liquid_artificial_pressure", "liquid_tension: true"],
    );
    expect(
        &ap("liquid_tension: true, liquid_artificial_pressure: Some(ArtificialStress(epsilon: 0.2, exponent: 0))"),
        &["numerics.liquid_artificial_pressure.exponent", "1..=12"],
    );
    expect(
        &ap("liquid_tension: true, liquid_artificial_pressure: Some(ArtificialStress(epsilon: -1.0))"),
        &["numerics.liquid_artificial_pressure.epsilon", "0.2"],
    );
}

#[test]
fn tension_limit_needs_tension_and_a_fraction() {
    let tl = |body: &str| edit("dt_max: 1e-3", &format!("dt_max: 1e-3, {body}"));
    expect(&tl("liquid_tension_below_ns: Some(0.05)"), &["numerics.liquid_tension_below_ns", "liquid_tension: true"]);
    expect(
        &tl("liquid_tension: true, liquid_tension_below_ns: Some(1.5)"),
        &["numerics.liquid_tension_below_ns", "[0, 1]"],
    );
    let bore = "liquid_tension_in: [Box(min: (0.0, 0.0, 0.0), max: (0.01, 0.01, 0.01))]";
    expect(&tl(bore), &["numerics.liquid_tension_in", "liquid_tension: true"]);
    expect(
        &tl("liquid_tension: true, liquid_tension_in: [Box(min: (0.0, 0.0, 0.02), max: (0.01, 0.01, 0.01))]"),
        &["numerics.liquid_tension_in[0]", "min ≤ max"],
    );
    expect(
        &tl("liquid_tension: true, liquid_tension_in: [Sphere(centre: (0.0, 0.0, 0.0), radius: -1.0)]"),
        &["numerics.liquid_tension_in[0].radius"],
    );
    let five = ["Sphere(centre: (0.0, 0.0, 0.0), radius: 0.001)"; 5].join(", ");
    expect(
        &tl(&format!("liquid_tension: true, liquid_tension_in: [{five}]")),
        &["numerics.liquid_tension_in", "limit of 4"],
    );
}

#[test]
fn dt_bound_never_met() {
    expect(&edit("dt_min: 1e-9, dt_max: 1e-3", "dt_min: 1e-2, dt_max: 1.0"), &["numerics.dt_min", "can never be met"]);
}

#[test]
fn fixed_dt_too_large() {
    expect(&edit("dt_max: 1e-3", "dt_max: 1e-3, fixed_dt: Some(1e-3)"), &["numerics.fixed_dt", "stability bound"]);
}

#[test]
fn periodic_axis_too_short() {
    expect(&edit("dx_liquid: Some(5.0e-4)", "dx_liquid: Some(2.0e-3)"), &["domain.periodic[0]", "search radii"]);
}

#[test]
fn negative_duration() {
    expect(&edit("duration: 0.1,", "duration: -1.0,"), &["duration", "> 0"]);
}

#[test]
fn absurd_gravity() {
    expect(&edit("gravity: (0.3675, 0.0, 0.0)", "gravity: (1e6, 0.0, 0.0)"), &["gravity", "absurd"]);
}

#[test]
fn empty_boundary_shape() {
    expect(&edit("max: (0.01, 0.0115, 0.0)", "max: (0.01, 0.0101, 0.0)"), &["boundaries[0]", "zero particles"]);
}

#[test]
fn absurd_particle_count() {
    let text = edit("dx_liquid: Some(5.0e-4)", "dx_liquid: Some(1.0e-6)").replace("dt_min: 1e-9", "dt_min: 1e-15");
    expect(&text, &["particles", "exceed the limit"]);
}

#[test]
fn override_errors_are_clear() {
    let ok = Scenario::from_str_with_overrides(BASE, "base.ron", &["numerics.dx_liquid=0.00025".into()])
        .expect("valid override");
    assert_eq!(ok.numerics.dx_liquid, Some(0.00025));
    let e =
        Scenario::from_str_with_overrides(BASE, "base.ron", &["numerics.dx_liquid=-1".into()]).unwrap_err().to_string();
    assert!(e.contains("numerics.dx_liquid") && e.contains("base.ron"), "{e}");
    let e =
        Scenario::from_str_with_overrides(BASE, "base.ron", &["numerics.nonsense=1".into()]).unwrap_err().to_string();
    assert!(e.contains("nonsense") && e.contains("dotted path"), "{e}");
    let e =
        Scenario::from_str_with_overrides(BASE, "base.ron", &["numerics.dx_liquid".into()]).unwrap_err().to_string();
    assert!(e.contains("missing `=`"), "{e}");
    let e =
        Scenario::from_str_with_overrides(BASE, "base.ron", &["liquid.viscosity=nan".into()]).unwrap_err().to_string();
    assert!(e.contains("finite"), "{e}");
    // Enum wrappers may be omitted in the path, and list entries are addressed by index.
    let ok =
        Scenario::from_str_with_overrides(BASE, "base.ron", &["particles.0.fraction=0.5".into()]).expect("enum path");
    assert!(matches!(ok.particles[0], perfuse::scenario::Generator::Box { fraction, .. } if fraction == 0.5));
    // A value of the wrong type or an unknown variant: the message names the field, the type's words
    // and the variants there are.
    let e = Scenario::from_str_with_overrides(BASE, "base.ron", &["boundaries.0.shape=Cube(side: 1)".into()])
        .unwrap_err()
        .to_string();
    assert!(e.contains("boundaries.0.shape") && e.contains("Cube") && e.contains("Sphere"), "{e}");
}

/// Whole enum values, lists of them and new structs are typed by the field they replace (RON spliced
/// into the scenario's own), integers where floats are expected included; the untyped shorthands
/// still work (a bare number or `null` for an optional field).
#[test]
fn overrides_take_whole_enum_values() {
    use perfuse::scenario::{Motion, Region};
    let base = Scenario::from_str_named(BASE, "base.ron").expect("base");
    let one = |spec: &str| base.with_override(spec).unwrap_or_else(|e| panic!("{spec}: {e}"));
    let s = one("boundaries.0.shape=Sphere(centre: (0.005, 0.01, 0), radius: 0.002)");
    assert_eq!(s.boundaries[0].shape, Region::Sphere { centre: [0.005, 0.01, 0.0], radius: 0.002 });
    let s = one("boundaries.0.motion=Translate(velocity: (0, -0.1, 0), stop: Some(0.5))");
    assert_eq!(s.boundaries[0].motion, Motion::Translate { velocity: [0.0, -0.1, 0.0], start: 0.0, stop: Some(0.5) });
    let s =
        one("numerics.liquid_tension_in=[Box(min: (0, 0, 0), max: (1, 1, 1)), Sphere(centre: (0, 0, 0), radius: 1)]");
    assert_eq!(s.numerics.liquid_tension_in.len(), 2);
    assert!(matches!(s.numerics.liquid_tension_in[1], Region::Sphere { radius, .. } if radius == 1.0));
    let s = one("particles.0=Sphere(phase: Liquid, centre: (0.005, 0, 0), radius: 0.004, fraction: 1)");
    assert!(matches!(s.particles[0], perfuse::scenario::Generator::Sphere { radius, .. } if radius == 0.004));
    // untyped shorthands
    assert_eq!(one("numerics.fixed_dt=1e-5").numerics.fixed_dt, Some(1e-5));
    assert_eq!(one("numerics.fixed_dt=Some(2e-5)").numerics.fixed_dt, Some(2e-5));
    assert_eq!(one("numerics.fixed_dt=null").numerics.fixed_dt, None);
    assert_eq!(one("name=\"quoted name\"").name, "quoted name");
    // the result validates as a file would
    let v = Scenario::from_str_with_overrides(
        BASE,
        "base.ron",
        &["boundaries.0.shape=Box(min: (0, 0.01, 0), max: (0.01, 0.012, 0))".into()],
    )
    .expect("valid");
    assert!(matches!(v.boundaries[0].shape, Region::Box { max, .. } if max[1] == 0.012));
}

/// The typed route writes each scenario out as RON and reads it back: every shipped scenario survives
/// that round trip unchanged.
#[test]
fn shipped_scenarios_round_trip_through_ron() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios");
    for entry in std::fs::read_dir(&dir).expect("assets/scenarios") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "ron") {
            let sc = Scenario::load(&path).unwrap_or_else(|e| panic!("{e}"));
            let same =
                sc.with_override("name=\"renamed\"").and_then(|s| s.with_override(&format!("name={:?}", sc.name)));
            let same = same.unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(same == sc, "{} changed on the way through RON", path.display());
        }
    }
}

#[test]
fn missing_file_is_an_io_error() {
    let e = Scenario::load(std::path::Path::new("/nonexistent/x.ron")).unwrap_err().to_string();
    assert!(e.contains("/nonexistent/x.ron") && e.contains("cannot read"), "{e}");
}

/// Every shipped scenario parses and validates, without a warning.
#[test]
fn shipped_scenarios_are_valid() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios");
    let mut n = 0;
    let mut warned = Vec::new();
    for entry in std::fs::read_dir(&dir).expect("assets/scenarios") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "ron") {
            let sc = Scenario::load(&path).unwrap_or_else(|e| panic!("{e}"));
            let name = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
            warned.extend(perfuse::scenario::warnings(&sc).into_iter().map(|w| format!("{name}: {w}")));
            n += 1;
        }
    }
    assert!(n >= 5, "expected the validation scenarios, found {n}");
    assert!(warned.is_empty(), "{warned:#?}");
}

/// The liver's moulded bed (`Boundary::mould`): a negative clearance, a bed without gravity (no
/// "down" to mould under) and a moving bed are refused, each naming the field.
#[test]
fn moulded_bed_errors() {
    let liver_path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenarios/liver.ron");
    let liver = std::fs::read_to_string(liver_path).expect("liver.ron");
    let bed = "shape: Box(min: (-0.105, -0.0395, -0.07), max: (0.105, 0.0, 0.07)),";
    let cases: [(&str, &str, &str); 4] = [
        ("Mould(clearance: 0.005", "Mould(clearance: -0.005", "boundaries[4].mould.clearance"),
        ("depth: 0.015))", "depth: NaN))", "boundaries[4].mould.depth"),
        ("gravity: (0.0, -9.81, 0.0)", "gravity: (0.0, 0.0, 0.0)", "boundaries[4].mould"),
        (
            bed,
            "shape: Box(min: (-0.105, -0.0395, -0.07), max: (0.105, 0.0, 0.07)), motion: Translate(velocity: (0.0, 0.01, 0.0)),",
            "boundaries[4].mould",
        ),
    ];
    for (from, to, needle) in cases {
        assert!(liver.contains(from), "test bug: `{from}` not in liver.ron");
        match Scenario::from_str_named(&liver.replacen(from, to, 1), liver_path) {
            Ok(_) => panic!("expected an error for `{to}`"),
            Err(e) => assert!(e.to_string().contains(needle), "expected `{needle}` in: {e}"),
        }
    }
}

/// Elastic ligaments: a negative or too-stiff frequency, a NaN damping ratio, a region that is not
/// finite, no region, and ligaments without a solid are refused, each naming its field (and, for the
/// stiffness, the bound).
#[test]
fn ligament_errors() {
    let liver_path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenarios/liver.ron");
    let liver = std::fs::read_to_string(liver_path).expect("liver.ron");
    let cases: [(&str, &str, &[&str]); 4] = [
        ("frequency: 15.0,", "frequency: -15.0,", &["ligaments.frequency", "> 0"]),
        // ζ = 1 at dt_max = 1 ms: at most 1/(2π·1e-3·2) ≈ 80 Hz
        ("frequency: 15.0,", "frequency: 200.0,", &["ligaments.frequency", "at most 80 Hz"]),
        ("damping_ratio: 1.0,", "damping_ratio: NaN,", &["ligaments.damping_ratio"]),
        ("-0.030314), radius: 0.025)", "-0.030314), radius: inf)", &["ligaments.regions[0]"]),
    ];
    for (from, to, needles) in cases {
        assert!(liver.contains(from), "test bug: `{from}` not in liver.ron");
        expect_named(&liver.replacen(from, to, 1), liver_path, needles);
    }
    let small = |phase: &str, ligaments: &str| {
        format!(
            r#"Scenario(
            name: "lig", dimensions: 3,
            domain: Domain(min: (-0.01, -0.01, -0.01), max: (0.01, 0.01, 0.01)),
            liquid: Some(Liquid(density: 1000.0, viscosity: 0.001, sound_speed: Some(10.0))),
            solid: {phase},
            numerics: Numerics(dx_solid: Some(0.001), dx_liquid: Some(0.001)),
            particles: [ Box(phase: Liquid, min: (-0.002, -0.002, -0.002), max: (0.002, 0.002, 0.002), fraction: 1.0) ],
            ligaments: Some(Ligaments({ligaments})),
            duration: 0.01,
        )"#
        )
    };
    let solid = "Some(Solid(density: 1000.0, c10: 1e4, c01: 0.0, k_s: 1e4, n_sat: 0.6, k_sat: 1e4))";
    let sphere = "regions: [Sphere(centre: (0.0, 0.0, 0.0), radius: 0.001)], frequency: 10.0";
    expect_named(&small(solid, "regions: [], frequency: 10.0"), "lig.ron", &["ligaments.regions"]);
    expect_named(&small("None", sphere), "lig.ron", &["there is no solid"]);
}

/// The capsule's stiffness ratio: below 1 (softer than the tissue it wraps), and so stiff that its
/// elastic waves outrun the scenario's numerical sound speed, are refused, naming the field.
#[test]
fn capsule_stiffness_errors() {
    let liver_path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenarios/liver.ron");
    let liver = std::fs::read_to_string(liver_path).expect("liver.ron");
    let line = liver.lines().find(|l| l.trim_start().starts_with("membrane: Some(")).expect("liver.ron has a capsule");
    for (ratio, needles) in [
        ("0.5", &["membrane.stiffness", "[1, 1000]"][..]),
        // √(4/3 · 2 kPa · 100 / 1060 kg/m³) ≈ 15.9 m/s > sound_speed_solid = 10 m/s
        ("100.0", &["membrane.stiffness", "15.86 m/s", "sound_speed_solid"][..]),
    ] {
        let membrane = format!(
            "    membrane: Some(Membrane(threshold: 0.5, count: 3, radius: 0.5, angle: 0.7853981633974483, stiffness: {ratio})),"
        );
        expect_named(&liver.replacen(line, &membrane, 1), liver_path, needles);
    }
}

/// Organ meshes and the new sections: a missing mesh file, a mesh in a 2-D scenario, a mesh placed
/// outside the domain, an absurd tool speed, a blade on an indenter, a critical stretch below 1, a bad
/// physiology scale.
#[test]
fn mesh_tool_fracture_and_physiology_errors() {
    let liver_path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenarios/liver.ron");
    let liver = std::fs::read_to_string(liver_path).expect("liver.ron");
    let named = |text: &str| match Scenario::from_str_named(text, liver_path) {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    };
    let cases: [(&str, &str, &[&str]); 5] = [
        ("\"../meshes/liver.obj\"", "\"../meshes/no_such_liver.obj\"", &["particles[0].file", "no_such_liver.obj"]),
        ("kind: Indenter, max_speed: 0.1)", "kind: Indenter, max_speed: 500.0)", &["boundaries[2].tool.max_speed"]),
        // Only a box-shaped scalpel has a blade to cut with.
        (
            "kind: Indenter, max_speed: 0.1)",
            "kind: Indenter, max_speed: 0.1, blade_cut: true)",
            &["boundaries[2].tool.blade_cut"],
        ),
        ("critical_stretch: Some(1.3)", "critical_stretch: Some(0.9)", &["solid.critical_stretch"]),
        ("volume_scale: 10.0", "volume_scale: -1.0", &["physiology.volume_scale"]),
    ];
    for (from, to, needles) in cases {
        assert!(liver.contains(from), "test bug: `{from}` not in liver.ron");
        let msg = named(&liver.replacen(from, to, 1));
        for n in needles {
            assert!(msg.contains(n), "expected `{n}` in: {msg}");
        }
    }
    // A mesh placed outside the domain.
    let moved = liver.replacen(
        "PerfusedMesh(file: \"../meshes/liver.obj\",",
        "PerfusedMesh(file: \"../meshes/liver.obj\", placement: (translate: (0.5, 0.0, 0.0)),",
        1,
    );
    assert_ne!(moved, liver);
    let msg = named(&moved);
    assert!(msg.contains("placement") && msg.contains("outside the domain"), "{msg}");
    // A mesh generator in a 2-D scenario.
    let flat = liver.replacen("dimensions: 3", "dimensions: 2", 1);
    let msg = named(&flat);
    assert!(msg.contains("3-D") || msg.contains("dimensions"), "{msg}");
    // Garbage in the mesh file itself.
    let dir = std::env::temp_dir().join(format!("perfuse-badmesh-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    std::fs::write(dir.join("bad.obj"), b"v 0 0 0\nf 1 2 3 4 5\n\x00\xff garbage").expect("write");
    let sc_path = dir.join("s.ron");
    let text = liver.replacen("\"../meshes/liver.obj\"", "\"bad.obj\"", 1);
    let msg = match Scenario::from_str_named(&text, &sc_path.display().to_string()) {
        Ok(_) => panic!("garbage mesh accepted"),
        Err(e) => e.to_string(),
    };
    assert!(msg.contains("bad.obj") && msg.contains("particles[0].file"), "{msg}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn emitter_and_sink_errors() {
    let with = |emitter: &str| edit("duration: 0.1,", &format!("duration: 0.1, {emitter}"));
    let inlet = |flow: &str, dir: &str| {
        with(&format!(
            "emitters: [ Emitter(name: \"in\", region: Box(min: (0.0, -0.01, 0.0), max: (0.001, 0.01, 0.0)), direction: {dir}, flow: {flow}) ],"
        ))
    };
    Scenario::from_str_named(&inlet("Constant(1e-6)", "(1.0, 0.0, 0.0)"), "ok.ron").expect("a valid inlet");
    expect(&inlet("Constant(-1e-6)", "(1.0, 0.0, 0.0)"), &["emitters[0].flow", "m³/s"]);
    expect(&inlet("Constant(1e-6)", "(0.0, 0.0, 1.0)"), &["emitters[0].direction", "zero"]);
    expect(&inlet("Table(times: [0.0, 0.0], rates: [1e-6, 1e-6])", "(1.0, 0.0, 0.0)"), &["times[1]", "increasing"]);
    expect(&inlet("Table(times: [0.0, 1.0], rates: [1e-6])", "(1.0, 0.0, 0.0)"), &["times", "one rate per time"]);
    expect(&inlet("Hepatic", "(1.0, 0.0, 0.0)"), &["physiology", "Hepatic"]);
    expect(
        &with(
            "emitters: [ Emitter(name: \"in\", region: Box(min: (0.0, 0.0, 0.0), max: (0.0001, 0.01, 0.0)), direction: (1.0, 0.0, 0.0), flow: Constant(1e-6)) ],",
        ),
        &["emitters[0].region", "no lattice site"],
    );
    expect(&with("liquid_capacity: Some(0),"), &["liquid_capacity", "out of range"]);
    expect(
        &with("sinks: [ Sink(name: \"out\", region: Sphere(centre: (0.005, 0.0, 0.0), radius: -1.0)) ],"),
        &["sinks[0].region.radius"],
    );
}

/// Surface-tension inputs (SPEC §3.12): contradictory C₁, an impossible equilibrium fraction, a negative
/// strength, a sheet off the domain.
#[test]
fn surface_tension_inputs() {
    let liquid = "sound_speed: Some(0.6))";
    expect(
        &edit(
            liquid,
            "sound_speed: Some(0.6), c1: 1.0, c1_from_equilibrium: Some(Equilibrium(solid_fraction: 0.3, liquid_fraction: 0.5)))",
        ),
        &["liquid.c1_from_equilibrium", "keep only one"],
    );
    expect(
        &edit(
            liquid,
            "sound_speed: Some(0.6), c1_from_equilibrium: Some(Equilibrium(solid_fraction: 0.3, liquid_fraction: 0.8)))",
        ),
        &["liquid.c1_from_equilibrium.liquid_fraction"],
    );
    expect(&edit(liquid, "sound_speed: Some(0.6), wicking: -0.07)"), &["liquid.wicking", "N/m"]);
    expect(
        &edit(liquid, "sound_speed: Some(0.6), cohesion: Some(Cohesion(liquid: 1e-6, boundary: -1.0)))"),
        &["liquid.cohesion.boundary"],
    );
    let sheet = edit(
        "particles: [ Box(phase: Liquid, min: (0.0, -0.01, 0.0), max: (0.01, 0.01, 0.0), fraction: 1.0) ],",
        "particles: [ Box(phase: Liquid, min: (0.0, -0.01, 0.0), max: (0.01, 0.01, 0.0), fraction: 1.0),
                      Sheet(centre: (0.02, 0.0, 0.0), size: (0.01, 0.0), fraction: 0.3) ],
         solid: Some(Solid(density: 1000.0, c10: 1e3, c01: 0.0, k_s: 1e4, n_sat: 0.3, k_sat: 0.0)),",
    )
    .replace(
        "numerics: Numerics(dx_liquid: Some(5.0e-4),",
        "numerics: Numerics(dx_liquid: Some(5.0e-4), dx_solid: Some(5.0e-4),",
    );
    expect(&sheet, &["particles[1].centre", "outside the domain"]);
}

/// Cavities (SPEC §7.8's needle hole) empty tissue: one in a scenario without solid, or with a NaN
/// corner, is refused naming `cavities[0]`; liquid generators may use different fractions (a primed
/// needle beside perfused tissue), and each gives its particles the mass of its own fraction.
#[test]
fn cavities_need_solid_and_liquid_fractions_may_differ() {
    expect(
        &edit("duration: 0.1,", "cavities: [ Box(min: (0.0, 0.0, 0.0), max: (0.001, 0.001, 0.0)) ], duration: 0.1,"),
        &["cavities[0]", "no solid"],
    );
    expect(
        &edit("duration: 0.1,", "cavities: [ Box(min: (NaN, 0.0, 0.0), max: (0.001, 0.001, 0.0)) ], duration: 0.1,"),
        &["cavities[0].min"],
    );
    let two = edit(
        "fraction: 1.0) ],",
        "fraction: 1.0), Box(phase: Liquid, min: (0.0, 0.0105, 0.0), max: (0.01, 0.0115, 0.0), fraction: 0.4) ],",
    )
    .replace("max: (0.01, 0.0115, 0.0))) ]", "max: (0.01, 0.0125, 0.0))) ]")
    .replace(
        "Box(min: (0.0, 0.01, 0.0), max: (0.01, 0.0125, 0.0))",
        "Box(min: (0.0, 0.0115, 0.0), max: (0.01, 0.0125, 0.0))",
    );
    let sc = Scenario::from_str_named(&two, "two.ron").expect("two liquid fractions are valid");
    let g = perfuse::scenario::generate(&sc);
    let (heavy, light): (Vec<f64>, Vec<f64>) = g.liquid.mass.iter().partition(|&&m| (m - g.mass_liquid).abs() < 1e-15);
    assert!(!heavy.is_empty() && !light.is_empty());
    assert!((light[0] / heavy[0] - 0.4).abs() < 1e-12, "{} / {}", light[0], heavy[0]);
}

/// A cavity in a perfused mesh empties the tissue's blood there but keeps the blood a later plain
/// generator places in it (a primed needle), even though the capsule step drops the mesh liquid
/// outside the capsule first and so shifts the liquid's indices.
#[test]
fn a_cavity_in_the_liver_empties_its_blood() {
    use perfuse::scenario::{Generator, Phase, Region};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/liver.ron");
    let cavity = Region::Box { min: [-0.02, -0.02, -0.02], max: [0.02, 0.02, 0.02] };
    let mut sc = Scenario::load(&path).expect("liver.ron");
    let before = perfuse::scenario::generate(&sc);
    sc.cavities = vec![cavity.clone()];
    sc.particles.push(Generator::Box {
        phase: Phase::Liquid,
        min: [-0.01, -0.01, -0.01],
        max: [0.01, 0.01, 0.01],
        fraction: 1.0,
        velocity: None,
    });
    let primed = perfuse::scenario::generate(&sc).liquid.mass.iter().filter(|&&m| m > before.mass_liquid * 2.0).count();
    assert!(primed > 0);
    sc.particles.pop();
    let after = perfuse::scenario::generate(&sc);
    let inside = |p: &[f64; 3]| cavity.contains(*p, 3);
    let (l0, s0) =
        (before.liquid.pos.iter().filter(|p| inside(p)).count(), before.solid.pos.iter().filter(|p| inside(p)).count());
    assert!(l0 > 0 && s0 > 0, "the cavity must cut the organ: {l0} liquid, {s0} solid");
    assert_eq!(after.liquid.pos.iter().filter(|p| inside(p)).count(), 0);
    assert_eq!(after.solid.pos.iter().filter(|p| inside(p)).count(), 0);
    // everything outside it stays
    assert_eq!(after.liquid.pos.len(), before.liquid.pos.len() - l0);
    assert_eq!(after.solid.pos.len(), before.solid.pos.len() - s0);
    // the primed box keeps every one of its particles: (2 cm / 5 mm)³ lattice sites
    assert_eq!(primed, 64, "primed particles kept");
}

/// Pressure outlets and the ambient pressure: a buffer needs a sink beyond it, a `Box`, a direction
/// and a suction well below the liquid's stiffness (BASE: k = ρc² = 360 Pa); p_a is a non-negative
/// pressure.
#[test]
fn outlet_inputs() {
    let sink = "sinks: [ Sink(name: \"out\", region: Box(min: (0.0, 0.0095, 0.0), max: (0.01, 0.01, 0.0))) ],";
    let outlet = |region: &str, pressure: &str, normal: &str| {
        format!("outlets: [ Outlet(name: \"suction\", region: {region}, pressure: {pressure}, normal: {normal}) ],")
    };
    let buffer = "Box(min: (0.0, 0.007, 0.0), max: (0.01, 0.0095, 0.0))";
    let with_both = |o: &str, s: &str| edit("    duration: 0.1,", &format!("    {o}\n    {s}\n    duration: 0.1,"));
    Scenario::from_str_named(&with_both(&outlet(buffer, "-100.0", "(0.0, 1.0, 0.0)"), sink), "ok.ron")
        .expect("a valid outlet");
    expect(&with_both(&outlet(buffer, "-100.0", "(0.0, 1.0, 0.0)"), ""), &["outlets", "no sink", "Sink("]);
    expect(
        &with_both(&outlet("Sphere(centre: (0.005, 0.008, 0.0), radius: 0.001)", "-100.0", "(0.0, 1.0, 0.0)"), sink),
        &["outlets[0].region", "Box"],
    );
    expect(&with_both(&outlet(buffer, "-100.0", "(0.0, 0.0, 0.0)"), sink), &["outlets[0].normal", "direction"]);
    expect(&with_both(&outlet(buffer, "-200.0", "(0.0, 1.0, 0.0)"), sink), &["outlets[0].pressure", "stiffness"]);
    expect(&edit("dt_max: 1e-3)", "dt_max: 1e-3, ambient_pressure: Some(-1.0))"), &["numerics.ambient_pressure", "Pa"]);
}

/// A box edge a hair short of a whole number of spacings (`scenario::warnings`): the generator
/// fills ⌊extent/Δx⌋ layers, so 0.0999 m at Δx = 0.01 m gives 9 layers where 10 were meant — a
/// warning naming the box, the axis and the extent that gives the layers meant; a wall alike; an
/// exact edge, or one deliberately half a spacing short, gives none.
#[test]
fn a_box_a_hair_short_of_a_layer_is_warned_about() {
    let base = r#"Scenario(
    name: "slip",
    dimensions: 2,
    domain: Domain(min: (-0.05, -0.05, 0.0), max: (0.15, 0.15, 0.0)),
    liquid: Some(Liquid(density: 1000.0, viscosity: 0.001, sound_speed: Some(10.0))),
    numerics: Numerics(dx_liquid: Some(0.01)),
    particles: [ Box(phase: Liquid, min: (0.0, 0.0, 0.0), max: (XMAX, 0.05, 0.0), fraction: 1.0) ],
    boundaries: [ Boundary(name: "floor", shape: Box(min: (-0.03, -0.03, 0.0), max: (0.13, WALL, 0.0))) ],
    duration: 0.01,
)"#;
    let load = |xmax: &str, wall: &str| {
        Scenario::from_str_named(&base.replace("XMAX", xmax).replace("WALL", wall), "slip.ron").expect("valid")
    };
    assert!(perfuse::scenario::warnings(&load("0.1", "0.0")).is_empty(), "exact edges");
    assert!(perfuse::scenario::warnings(&load("0.095", "-0.005")).is_empty(), "half a spacing short is meant");
    let w = perfuse::scenario::warnings(&load("0.0999", "-0.0001"));
    assert_eq!(w.len(), 2, "{w:#?}");
    assert!(
        w[0].starts_with("particles[0]") && w[0].contains("along x") && w[0].contains("9 layers, not 10"),
        "{}",
        w[0]
    );
    assert!(w[0].contains("= 0.1 m for 10"), "gives the extent for the layers meant: {}", w[0]);
    assert!(w[1].starts_with("boundaries[0] `floor`") && w[1].contains("along y"), "{}", w[1]);
}
