//! Parameter validation: every numeric field finite and in its physical range, settings consistent
//! with each other, and the time-step bounds reachable. Each problem names the field and the fix.

use super::generate::lattice_count;
use super::{Flow, Generator, InitialVelocity, Motion, Phase, PressureMode, Problem, Region, Scenario, ToolKind};

/// Most particles a scenario may generate (all sets together): beyond this a desktop run is absurd.
pub const MAX_PARTICLES: usize = 20_000_000;

struct Check;

impl Check {
    fn fail(field: impl Into<String>, problem: impl Into<String>, fix: impl Into<String>) -> Problem {
        Problem { field: field.into(), problem: problem.into(), fix: fix.into() }
    }
    fn finite(field: &str, v: f64) -> Result<(), Problem> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(Check::fail(field, format!("{v} is not a finite number"), "give a finite value in SI units"))
        }
    }
    fn positive(field: &str, v: f64, fix: &str) -> Result<(), Problem> {
        Check::finite(field, v)?;
        if v > 0.0 { Ok(()) } else { Err(Check::fail(field, format!("must be > 0, got {v}"), fix)) }
    }
    fn non_negative(field: &str, v: f64, fix: &str) -> Result<(), Problem> {
        Check::finite(field, v)?;
        if v >= 0.0 { Ok(()) } else { Err(Check::fail(field, format!("must be ≥ 0, got {v}"), fix)) }
    }
    fn range(field: &str, v: f64, lo: f64, hi: f64, fix: &str) -> Result<(), Problem> {
        Check::finite(field, v)?;
        if v >= lo && v <= hi {
            Ok(())
        } else {
            Err(Check::fail(field, format!("must lie in [{lo}, {hi}], got {v}"), fix))
        }
    }
    fn vec(field: &str, v: [f64; 3]) -> Result<(), Problem> {
        for (a, x) in v.iter().enumerate() {
            Check::finite(&format!("{field}[{a}]"), *x)?;
        }
        Ok(())
    }
}

pub fn validate(s: &Scenario) -> Result<(), Problem> {
    if s.dimensions != 2 && s.dimensions != 3 {
        return Err(Check::fail(
            "dimensions",
            format!("must be 2 or 3, got {}", s.dimensions),
            "write dimensions: 2 or 3",
        ));
    }
    if s.name.trim().is_empty() {
        return Err(Check::fail("name", "is empty", "give the scenario a short name"));
    }
    let d = s.dimensions as usize;
    Check::vec("domain.min", s.domain.min)?;
    Check::vec("domain.max", s.domain.max)?;
    for a in 0..d {
        if s.domain.max[a] <= s.domain.min[a] {
            return Err(Check::fail(
                format!("domain.max[{a}]"),
                format!("{} is not above domain.min[{a}] = {}", s.domain.max[a], s.domain.min[a]),
                "make the domain's upper corner larger than its lower corner on every axis",
            ));
        }
    }
    if d == 2 && s.domain.periodic[2] {
        return Err(Check::fail("domain.periodic", "z is periodic in a 2-D scenario", "set the third entry to false"));
    }
    Check::vec("gravity", s.gravity)?;
    let g = (s.gravity[0].powi(2) + s.gravity[1].powi(2) + s.gravity[2].powi(2)).sqrt();
    if g > 1000.0 {
        return Err(Check::fail("gravity", format!("|g| = {g} m/s² is absurd"), "use m/s², e.g. (0, 0, -9.81)"));
    }
    Check::positive("duration", s.duration, "give the simulated time in seconds, e.g. 1.0")?;
    if s.duration > 1e4 {
        return Err(Check::fail(
            "duration",
            format!("{} s is absurd for an explicit SPH run", s.duration),
            "use seconds",
        ));
    }

    if let Some(l) = &s.liquid {
        Check::positive("liquid.density", l.density, "give ρ₀ in kg/m³, e.g. 1000")?;
        Check::non_negative("liquid.viscosity", l.viscosity, "give η in Pa·s, e.g. 0.35")?;
        Check::finite("liquid.c1", l.c1)?;
        if let Some(eq) = &l.c1_from_equilibrium {
            if l.c1 != 0.0 {
                return Err(Check::fail(
                    "liquid.c1_from_equilibrium",
                    "both `c1` and `c1_from_equilibrium` are given",
                    "keep only one of them",
                ));
            }
            Check::range(
                "liquid.c1_from_equilibrium.solid_fraction",
                eq.solid_fraction,
                1e-3,
                0.999,
                "nˢ of the porous solid, e.g. 0.3",
            )?;
            Check::range(
                "liquid.c1_from_equilibrium.liquid_fraction",
                eq.liquid_fraction,
                1e-3,
                1.0 - eq.solid_fraction,
                "nˡ_eq must lie in (0, 1 − nˢ] (C₁ ≥ 0), e.g. 0.5",
            )?;
        }
        Check::non_negative("liquid.wicking", l.wicking, "give γ of (3.4) in N/m, e.g. 0.0728 (water)")?;
        if let Some(c) = &l.cohesion {
            Check::non_negative("liquid.cohesion.liquid", c.liquid, "give s_ll of (3.3) in N, e.g. 1e-6")?;
            Check::non_negative("liquid.cohesion.boundary", c.boundary, "give s_lb of (3.3) in N, e.g. 5e-7")?;
        }
        match (l.stiffness, l.sound_speed) {
            (Some(_), Some(_)) => {
                return Err(Check::fail(
                    "liquid.stiffness",
                    "both `stiffness` and `sound_speed` are given (contradictory: k = ρ₀c²)",
                    "keep only one of them",
                ));
            }
            (None, None) => {
                return Err(Check::fail(
                    "liquid.sound_speed",
                    "neither `stiffness` nor `sound_speed` is given",
                    "add sound_speed: Some(10.0) (m/s) or stiffness: Some(1e5) (Pa)",
                ));
            }
            (Some(k), None) => Check::positive("liquid.stiffness", k, "give k in Pa, e.g. 1e5")?,
            (None, Some(c)) => Check::positive("liquid.sound_speed", c, "give c in m/s, e.g. 10")?,
        }
    }
    if let Some(m) = &s.solid {
        Check::positive("solid.density", m.density, "give ρ₀ in kg/m³, e.g. 1000")?;
        Check::non_negative("solid.c10", m.c10, "Mooney–Rivlin C10 is in Pa and must be ≥ 0")?;
        Check::non_negative("solid.c01", m.c01, "Mooney–Rivlin C01 is in Pa and must be ≥ 0")?;
        Check::non_negative("solid.k_s", m.k_s, "give k_s in Pa, e.g. 1e5")?;
        Check::non_negative("solid.k_sat", m.k_sat, "give k_sat in Pa, e.g. 1e5")?;
        Check::range("solid.n_sat", m.n_sat, 1e-3, 1.0, "nˢ_sat is a volume fraction, e.g. 0.6")?;
        Check::non_negative("solid.friction", m.friction, "give K̄ in Pa·s/m², e.g. 1e6")?;
        if let Some(lc) = m.critical_stretch {
            Check::range("solid.critical_stretch", lc, 1.0, 10.0, "λ_c is r/r₀ at rupture, e.g. 1.3 (30 % strain)")?;
        }
        if m.k_s + m.k_sat <= 0.0 {
            return Err(Check::fail(
                "solid.k_s",
                "k_s + k_sat = 0: the solid would have no volumetric stiffness",
                "give k_s > 0",
            ));
        }
    }

    let n = &s.numerics;
    Check::range("numerics.h_over_dx", n.h_over_dx, 1.0, 2.0, "the thesis allows 1 ≤ h/Δx ≤ 2; 1.3 is usual")?;
    let mut has_liquid = false;
    let mut has_solid = false;
    for g in &s.particles {
        match g {
            Generator::Box { phase, .. } | Generator::Sphere { phase, .. } => match phase {
                Phase::Liquid => has_liquid = true,
                Phase::Solid => has_solid = true,
            },
            Generator::PerfusedBlock { .. } | Generator::PerfusedMesh { .. } => {
                has_liquid = true;
                has_solid = true;
            }
            Generator::Sheet { .. } => has_solid = true,
        }
    }
    if s.particles.is_empty() && s.emitters.is_empty() {
        return Err(Check::fail(
            "particles",
            "no particle generator (and no emitter)",
            "add at least one generator, e.g. Box(phase: Liquid, ...), or an emitter",
        ));
    }
    if has_liquid && s.liquid.is_none() {
        return Err(Check::fail(
            "liquid",
            "liquid particles are generated but no liquid material is given",
            "add liquid: Some(Liquid(...))",
        ));
    }
    if has_solid && s.solid.is_none() {
        return Err(Check::fail(
            "solid",
            "solid particles are generated but no solid material is given",
            "add solid: Some(Solid(...))",
        ));
    }
    let smallest_extent = (0..d).map(|a| s.domain.max[a] - s.domain.min[a]).fold(f64::INFINITY, f64::min);
    let check_dx = |field: &str, v: Option<f64>, needed: bool| -> Result<Option<f64>, Problem> {
        match v {
            None if needed => {
                Err(Check::fail(field, "is required by the generated particles", "give the lattice spacing in metres"))
            }
            None => Ok(None),
            Some(x) => {
                Check::positive(field, x, "give the lattice spacing in metres, e.g. 0.001")?;
                if x > smallest_extent {
                    return Err(Check::fail(
                        field,
                        format!("Δx = {x} m is larger than the domain ({smallest_extent} m)"),
                        "use a spacing much smaller than the domain",
                    ));
                }
                Ok(Some(x))
            }
        }
    };
    let dx_l = check_dx("numerics.dx_liquid", n.dx_liquid, has_liquid)?;
    let dx_s = check_dx("numerics.dx_solid", n.dx_solid, has_solid)?;
    if let Some(h) = n.h_liquid {
        Check::positive("numerics.h_liquid", h, "give h in metres")?;
    }
    if let Some(h) = n.h_solid {
        Check::positive("numerics.h_solid", h, "give h in metres")?;
    }
    let h_l = dx_l.map(|dx| n.h_liquid.unwrap_or(n.h_over_dx * dx));
    let h_s = dx_s.map(|dx| n.h_solid.unwrap_or(n.h_over_dx * dx));
    let r_max = 2.0 * h_l.unwrap_or(0.0).max(h_s.unwrap_or(0.0));
    for a in 0..d {
        if s.domain.periodic[a] {
            let len = s.domain.max[a] - s.domain.min[a];
            if len < 3.0 * r_max {
                return Err(Check::fail(
                    format!("domain.periodic[{a}]"),
                    format!("periodic length {len} m is shorter than three search radii ({} m)", 3.0 * r_max),
                    "lengthen the periodic axis or refine Δx",
                ));
            }
        }
    }

    let av = &n.artificial_viscosity;
    Check::non_negative("numerics.artificial_viscosity.alpha", av.alpha, "α_d ≥ 0, default 1")?;
    Check::non_negative("numerics.artificial_viscosity.beta", av.beta, "β_d ≥ 0, default 1")?;
    Check::positive("numerics.artificial_viscosity.gamma", av.gamma, "γ_d > 0, default 0.01")?;
    Check::non_negative("numerics.artificial_stress.epsilon", n.artificial_stress.epsilon, "ε ≥ 0, default 0.3")?;
    if n.artificial_stress.exponent == 0 || n.artificial_stress.exponent > 12 {
        return Err(Check::fail(
            "numerics.artificial_stress.exponent",
            format!("{} is outside 1..=12", n.artificial_stress.exponent),
            "the thesis uses 4",
        ));
    }
    if let Some(v) = n.liquid_tension_below_ns {
        needs_tension(n, "liquid_tension_below_ns")?;
        Check::range("numerics.liquid_tension_below_ns", v, 0.0, 1.0, "a solid fraction nˢ, e.g. 0.05")?;
    }
    if !n.liquid_tension_in.is_empty() {
        needs_tension(n, "liquid_tension_in")?;
    }
    if n.liquid_tension_in.len() > MAX_TENSION_REGIONS {
        return Err(Check::fail(
            "numerics.liquid_tension_in",
            format!("{} regions exceed the limit of {MAX_TENSION_REGIONS}", n.liquid_tension_in.len()),
            "merge regions into fewer boxes or spheres",
        ));
    }
    for (k, r) in n.liquid_tension_in.iter().enumerate() {
        let f = format!("numerics.liquid_tension_in[{k}]");
        check_region(&f, r)?;
        if let Region::Box { min, max } = r
            && (0..3).any(|a| min[a] > max[a])
        {
            return Err(Check::fail(
                f,
                format!("the box's min {min:?} exceeds its max {max:?} on some axis, so it holds nothing"),
                "give min ≤ max on every axis",
            ));
        }
    }
    if let Some(a) = &n.liquid_artificial_pressure {
        needs_tension(n, "liquid_artificial_pressure")?;
        Check::range(
            "numerics.liquid_artificial_pressure.epsilon",
            a.epsilon,
            0.0,
            1.0,
            "ε in [0, 1]; Monaghan (2000) uses 0.2 for liquids",
        )?;
        if a.exponent == 0 || a.exponent > 12 {
            return Err(Check::fail(
                "numerics.liquid_artificial_pressure.exponent",
                format!("{} is outside 1..=12", a.exponent),
                "Monaghan (2000) uses 4",
            ));
        }
    }
    Check::range("numerics.xsph.solid", n.xsph.solid, 0.0, 1.0, "ε̃ lies in [0, 1], default 0.5")?;
    Check::range("numerics.xsph.liquid", n.xsph.liquid, 0.0, 1.0, "ε̃ lies in [0, 1], default 0")?;
    let c = &n.cfl;
    Check::range("numerics.cfl.factor", c.factor, 1e-3, 2.0, "C_Δt near 1")?;
    Check::range("numerics.cfl.viscous", c.viscous, 1e-4, 1.0, "thesis: 0.125")?;
    Check::range("numerics.cfl.sound", c.sound, 1e-4, 1.0, "thesis: 0.25")?;
    Check::range("numerics.cfl.force", c.force, 1e-4, 1.0, "thesis: 0.25")?;
    Check::range("numerics.cfl.friction", c.friction, 1e-4, 2.0, "default 0.5")?;
    Check::positive("numerics.dt_min", n.dt_min, "give seconds, e.g. 1e-9")?;
    Check::positive("numerics.dt_max", n.dt_max, "give seconds, e.g. 1e-3")?;
    if n.dt_max < n.dt_min {
        return Err(Check::fail(
            "numerics.dt_max",
            format!("{} s is below dt_min = {} s", n.dt_max, n.dt_min),
            "make dt_max ≥ dt_min",
        ));
    }
    if let Some(v) = n.sound_speed_liquid {
        Check::positive("numerics.sound_speed_liquid", v, "m/s")?;
    }
    if let Some(v) = n.sound_speed_solid {
        Check::positive("numerics.sound_speed_solid", v, "m/s")?;
    }
    if let Some(v) = n.max_speed {
        Check::positive("numerics.max_speed", v, "m/s")?;
    }
    if let Some(v) = n.ambient_pressure {
        Check::range(
            "numerics.ambient_pressure",
            v,
            0.0,
            1e7,
            "an ambient pressure in Pa of order the suction it must carry (1e4 for a syringe's −5 kPa)",
        )?;
    }
    if let Some(v) = n.hourglass {
        Check::range(
            "numerics.hourglass",
            v,
            1e-6,
            10.0,
            "a dimensionless coefficient, e.g. 2; omit it to switch off",
        )?;
    }

    // A-priori time-step bound from the sound and viscous limits of (2.70): a dt_min above it, or a
    // fixed step beyond it, can never be met.
    let mut bound = f64::INFINITY;
    let mut c_max: f64 = 0.0;
    if let (Some(l), Some(h)) = (&s.liquid, h_l) {
        let k = l.stiffness.unwrap_or_else(|| l.density * l.sound_speed.unwrap_or(0.0).powi(2));
        let cl = n.sound_speed_liquid.unwrap_or((k / l.density).sqrt());
        c_max = c_max.max(cl);
        if l.viscosity > 0.0 {
            // Smallest apparent density expected: the smallest liquid fraction generated.
            let n0 = min_fraction(s, Phase::Liquid).unwrap_or(1.0);
            bound = bound.min(c.viscous * n0 * l.density * h * h / l.viscosity);
        }
    }
    if let (Some(m), Some(_)) = (&s.solid, h_s) {
        let n0 = min_fraction(s, Phase::Solid).unwrap_or(1.0);
        let g_mod = 2.0 * (m.c10 + m.c01);
        let cs = n
            .sound_speed_solid
            .unwrap_or(((m.k_s + m.k_sat) / m.density + 4.0 / 3.0 * g_mod / (n0 * m.density)).sqrt());
        c_max = c_max.max(cs);
    }
    let h_min = h_l.unwrap_or(f64::INFINITY).min(h_s.unwrap_or(f64::INFINITY));
    if c_max > 0.0 {
        bound = bound.min(c.sound * h_min / (3.0 * c_max));
    }
    bound = bound.min(n.dt_max) * c.factor;
    if bound < n.dt_min {
        return Err(Check::fail(
            "numerics.dt_min",
            format!(
                "the sound/viscous limit of (2.70) gives Δt ≤ {bound:.3e} s, below dt_min = {:.3e} s: it can never be met",
                n.dt_min
            ),
            "lower dt_min, coarsen Δx or lower the sound speed",
        ));
    }
    if let Some(f) = n.fixed_dt {
        Check::positive("numerics.fixed_dt", f, "give seconds")?;
        if f > 1.05 * bound {
            return Err(Check::fail(
                "numerics.fixed_dt",
                format!("{f:.3e} s exceeds the stability bound {bound:.3e} s by more than 5 %"),
                "remove fixed_dt or make it smaller",
            ));
        }
    }
    let steps = s.duration / bound;
    if steps > 1e10 {
        return Err(Check::fail("duration", format!("needs ≈ {steps:.2e} steps"), "shorten the run or coarsen Δx"));
    }

    // Generators, boundaries and regions.
    let mut total = 0usize;
    let mut solid_fraction: Option<f64> = None;
    for (i, g) in s.particles.iter().enumerate() {
        let f = format!("particles[{i}]");
        let (count, phase_fracs): (usize, Vec<(Phase, f64)>) = match g {
            Generator::Box { phase, min, max, fraction, velocity } => {
                check_box(&f, *min, *max, d, s)?;
                Check::range(&format!("{f}.fraction"), *fraction, 1e-3, 1.0, "n₀ is a volume fraction in (0, 1]")?;
                check_velocity(&f, velocity)?;
                let dx = phase_dx(*phase, dx_l, dx_s);
                (lattice_count(&super::Region::Box { min: *min, max: *max }, dx, d), vec![(*phase, *fraction)])
            }
            Generator::Sphere { phase, centre, radius, fraction, velocity } => {
                Check::vec(&format!("{f}.centre"), *centre)?;
                Check::positive(&format!("{f}.radius"), *radius, "give the radius in metres")?;
                Check::range(&format!("{f}.fraction"), *fraction, 1e-3, 1.0, "n₀ is a volume fraction in (0, 1]")?;
                check_velocity(&f, velocity)?;
                let dx = phase_dx(*phase, dx_l, dx_s);
                (
                    lattice_count(&super::Region::Sphere { centre: *centre, radius: *radius }, dx, d),
                    vec![(*phase, *fraction)],
                )
            }
            Generator::PerfusedBlock { min, max, solid_fraction, liquid_fraction } => {
                check_box(&f, *min, *max, d, s)?;
                check_perfused_fractions(&f, *solid_fraction, *liquid_fraction)?;
                let r = super::Region::Box { min: *min, max: *max };
                (
                    lattice_count(&r, phase_dx(Phase::Solid, dx_l, dx_s), d)
                        + lattice_count(&r, phase_dx(Phase::Liquid, dx_l, dx_s), d),
                    vec![(Phase::Solid, *solid_fraction), (Phase::Liquid, *liquid_fraction)],
                )
            }
            Generator::Sheet { centre, size, fraction } => {
                Check::vec(&format!("{f}.centre"), *centre)?;
                Check::positive(&format!("{f}.size.0"), size.0, "give the sheet's x extent in metres")?;
                if d == 3 {
                    Check::positive(&format!("{f}.size.1"), size.1, "give the sheet's y extent in metres")?;
                }
                Check::range(&format!("{f}.fraction"), *fraction, 1e-3, 1.0, "nˢ is a volume fraction in (0, 1]")?;
                let pts = super::generate::sheet_points(*centre, *size, phase_dx(Phase::Solid, dx_l, dx_s), d);
                for (k, p) in pts.iter().enumerate().filter(|(k, _)| *k == 0 || *k == pts.len() - 1) {
                    for a in 0..d {
                        if p[a] < s.domain.min[a] || p[a] > s.domain.max[a] {
                            return Err(Check::fail(
                                format!("{f}.centre"),
                                format!("sheet particle {k} at {p:?} lies outside the domain"),
                                "move or shrink the sheet, or enlarge the domain",
                            ));
                        }
                    }
                }
                (pts.len(), vec![(Phase::Solid, *fraction)])
            }
            Generator::PerfusedMesh { file, placement, solid_fraction, liquid_fraction } => {
                if d != 3 {
                    return Err(Check::fail(
                        f.to_string(),
                        "a mesh generator needs a 3-D scenario",
                        "set dimensions: 3, or use Box/PerfusedBlock in 2-D",
                    ));
                }
                check_perfused_fractions(&f, *solid_fraction, *liquid_fraction)?;
                let path = s.resolve(file);
                let fail = |e: super::mesh::MeshError| {
                    Check::fail(format!("{f}.file"), e.to_string(), "fix or replace the mesh file named above")
                };
                placement.check(&path.display().to_string()).map_err(&fail)?;
                let (mesh, _) = super::mesh::load_and_validate(&path).map_err(&fail)?;
                let mesh = mesh.transformed(placement);
                let (lo, hi) = mesh.bounds();
                for a in 0..3 {
                    if lo[a] < s.domain.min[a] || hi[a] > s.domain.max[a] {
                        return Err(Check::fail(
                            format!("{f}.placement"),
                            format!(
                                "the placed mesh spans {:?}..{:?}, outside the domain {:?}..{:?}",
                                lo, hi, s.domain.min, s.domain.max
                            ),
                            "move it with placement.translate, shrink it with placement.scale/fit_size, or enlarge the domain",
                        ));
                    }
                }
                let mut count = 0;
                for phase in [Phase::Solid, Phase::Liquid] {
                    let dx = phase_dx(phase, dx_l, dx_s);
                    let offset = super::generate::mesh_lattice_offset(phase, dx);
                    count += super::mesh::try_sample_interior(&mesh, dx, offset).map_err(&fail)?.len();
                }
                (count, vec![(Phase::Solid, *solid_fraction), (Phase::Liquid, *liquid_fraction)])
            }
        };
        if count == 0 {
            return Err(Check::fail(
                f,
                "generates zero particles (the region is thinner than one lattice spacing)",
                "enlarge the region or refine Δx",
            ));
        }
        // The solid has one particle mass; liquid generators may differ (a needle primed with pure
        // blood beside the tissue's perfusing blood, SPEC §7.8): each gives its particles the mass of
        // its own fraction, and the first sets the scenario's n₀ (boundary masses, emitters).
        for (_, fr) in phase_fracs.into_iter().filter(|(phase, _)| *phase == Phase::Solid) {
            match solid_fraction {
                Some(prev) if (prev - fr).abs() > 1e-12 => {
                    return Err(Check::fail(
                        format!("{f}.fraction"),
                        format!(
                            "Solid particles use fraction {fr} here and {prev} elsewhere: each phase has one particle mass"
                        ),
                        "use one initial fraction per phase",
                    ));
                }
                _ => solid_fraction = Some(fr),
            }
        }
        total += count;
    }
    for (i, b) in s.boundaries.iter().enumerate() {
        let f = format!("boundaries[{i}]");
        if let Some(sp) = b.spacing {
            Check::positive(&format!("{f}.spacing"), sp, "give Δx_b in metres")?;
        }
        let sp = b.spacing.or(dx_s).or(dx_l).unwrap_or(1.0);
        check_region(&format!("{f}.shape"), &b.shape)?;
        let count = lattice_count(&b.shape, sp, d);
        if count == 0 {
            return Err(Check::fail(
                f,
                format!("boundary `{}` generates zero particles", b.name),
                "make the shape at least one spacing thick",
            ));
        }
        total += count;
        match &b.motion {
            Motion::Static => {}
            Motion::Translate { velocity, start, stop } => {
                Check::vec(&format!("{f}.motion.velocity"), *velocity)?;
                Check::non_negative(&format!("{f}.motion.start"), *start, "seconds")?;
                if let Some(st) = stop
                    && *st < *start
                {
                    return Err(Check::fail(format!("{f}.motion.stop"), "stop is before start", "make stop ≥ start"));
                }
            }
            Motion::Oscillate { amplitude, frequency, phase } => {
                Check::vec(&format!("{f}.motion.amplitude"), *amplitude)?;
                Check::positive(&format!("{f}.motion.frequency"), *frequency, "Hz")?;
                Check::finite(&format!("{f}.motion.phase"), *phase)?;
            }
        }
        if let PressureMode::Prescribed { density, pressure } = &b.pressure {
            Check::positive(&format!("{f}.pressure.density"), *density, "kg/m³")?;
            Check::finite(&format!("{f}.pressure.pressure"), *pressure)?;
        }
        if let Some(mu) = b.friction {
            Check::range(
                &format!("{f}.friction"),
                mu,
                0.0,
                2.0,
                "give Some(μ) with μ in [0, 2] (tissue on a tray ~0.3–0.6; 0 is frictionless), or leave it out",
            )?;
        }
        if let Some(m) = &b.mould {
            Check::positive(&format!("{f}.mould.clearance"), m.clearance, "metres, about the solid spacing Δx_s")?;
            Check::positive(&format!("{f}.mould.depth"), m.depth, "metres, at least the support radius 2.6Δx")?;
            let fix = "a moulded bed is a static support under the tissue: remove `mould`, or the motion / tool";
            if b.motion != Motion::Static || b.tool.is_some() {
                return Err(Check::fail(format!("{f}.mould"), "a moulded bed cannot move or be a tool", fix));
            }
            if s.solid.is_none() || s.gravity.iter().all(|g| *g == 0.0) {
                return Err(Check::fail(
                    format!("{f}.mould"),
                    "a bed is moulded to the tissue's underside, which needs a solid and gravity (\"down\")",
                    "add the solid and a gravity, or remove `mould`",
                ));
            }
        }
        if let Some(tool) = &b.tool {
            Check::positive(&format!("{f}.tool.max_speed"), tool.max_speed, "m/s")?;
            if tool.max_speed > 100.0 {
                return Err(Check::fail(
                    format!("{f}.tool.max_speed"),
                    format!("{} m/s is beyond any surgical tool", tool.max_speed),
                    "give at most 100 m/s (a projectile); a scalpel moves at ~0.01–0.1 m/s",
                ));
            }
            if tool.blade_cut && !(tool.kind == ToolKind::Scalpel && matches!(b.shape, Region::Box { .. })) {
                return Err(Check::fail(
                    format!("{f}.tool.blade_cut"),
                    "only a scalpel shaped as a Box has a blade to cut with",
                    "remove blade_cut, or make the object Tool(kind: Scalpel, …) with shape: Box(…)",
                ));
            }
        }
    }
    if let Some(ph) = &s.physiology {
        Check::range(
            "physiology.volume_scale",
            ph.volume_scale,
            1e-3,
            1e4,
            "physiological per simulated volume, e.g. 10",
        )?;
        if let Err(e) = ph.cardio.validate() {
            return Err(Check::fail("physiology.cardio", e.to_string(), "give a value in the stated range"));
        }
    }
    check_emitters(s, d)?;
    for (i, r) in s.fixed_regions.iter().enumerate() {
        check_region(&format!("fixed_regions[{i}]"), r)?;
        if s.solid.is_none() {
            return Err(Check::fail(
                format!("fixed_regions[{i}]"),
                "fixed regions hold solid particles, but there is no solid",
                "remove it or add solid particles",
            ));
        }
    }
    if let Some(lig) = &s.ligaments {
        check_ligaments(s, lig)?;
    }
    for (i, r) in s.cavities.iter().enumerate() {
        check_region(&format!("cavities[{i}]"), r)?;
        if s.solid.is_none() {
            return Err(Check::fail(
                format!("cavities[{i}]"),
                "a cavity removes solid particles, but there is no solid",
                "remove it or add solid particles",
            ));
        }
    }
    if total > MAX_PARTICLES {
        return Err(Check::fail(
            "particles",
            format!("≈ {total} particles exceed the limit of {MAX_PARTICLES}"),
            "coarsen Δx with --set numerics.dx_…",
        ));
    }
    if let Some(m) = &s.membrane {
        if s.solid.is_none() {
            return Err(Check::fail(
                "membrane",
                "a membrane wraps the solid, but there is no solid",
                "remove it or add solid particles",
            ));
        }
        Check::range("membrane.threshold", m.threshold, 0.05, 2.0, "δ_mem/Δx_s; 0.5 selects the outer layer")?;
        Check::range("membrane.radius", m.radius, 0.0, 1.0, "r_e/Δx_s, e.g. 0.5")?;
        Check::finite("membrane.angle", m.angle)?;
        Check::range(
            "membrane.stiffness",
            m.stiffness,
            1.0,
            1000.0,
            "the capsule's C10, C01 over the tissue's, e.g. 1 (thesis) or 10",
        )?;
        // The capsule's elastic waves must stay below the numerical sound speed when one is given (as
        // the derived one includes them, `Params::new`).
        if let (Some(mat), Some(c)) = (&s.solid, s.numerics.sound_speed_solid) {
            let wave = (4.0 / 3.0 * 2.0 * (mat.c10 + mat.c01) * m.stiffness / mat.density).sqrt();
            if wave > c {
                return Err(Check::fail(
                    "membrane.stiffness",
                    format!(
                        "the capsule's elastic wave speed {wave:.2} m/s exceeds numerics.sound_speed_solid = {c} m/s"
                    ),
                    "lower the ratio, or raise sound_speed_solid",
                ));
            }
        }
        if m.count > 12 {
            return Err(Check::fail(
                "membrane.count",
                format!("{} children per particle is absurd", m.count),
                "the thesis quadruples the surface count: 3",
            ));
        }
    }
    if let Some(r) = &s.relaxation {
        Check::non_negative("relaxation.duration", r.duration, "seconds")?;
        Check::non_negative("relaxation.damping", r.damping, "1/s, e.g. 20")?;
    }
    if let Some(fi) = s.output.frame_interval {
        Check::positive("output.frame_interval", fi, "seconds between frames")?;
        if s.duration / fi > 1e5 {
            return Err(Check::fail(
                "output.frame_interval",
                format!("{} frames would be written", s.duration / fi),
                "use a larger interval",
            ));
        }
    }
    for (i, p) in s.output.probes.iter().enumerate() {
        check_region(&format!("output.probes[{i}].region"), &p.region)?;
    }
    Ok(())
}

/// nˢ and nˡ of a perfused generator: each a volume fraction, together at most saturation (2.1).
fn check_perfused_fractions(f: &str, solid: f64, liquid: f64) -> Result<(), Problem> {
    Check::range(&format!("{f}.solid_fraction"), solid, 1e-3, 1.0, "a volume fraction, e.g. 0.6")?;
    Check::range(&format!("{f}.liquid_fraction"), liquid, 1e-3, 1.0, "a volume fraction, e.g. 0.4")?;
    if solid + liquid > 1.0 + 1e-9 {
        return Err(Check::fail(
            format!("{f}.liquid_fraction"),
            format!("nˢ + nˡ = {} exceeds 1 (saturation (2.1))", solid + liquid),
            "make the fractions sum to at most 1",
        ));
    }
    Ok(())
}

fn min_fraction(s: &Scenario, want: Phase) -> Option<f64> {
    s.particles
        .iter()
        .filter_map(|g| match g {
            Generator::Box { phase, fraction, .. } | Generator::Sphere { phase, fraction, .. } if *phase == want => {
                Some(*fraction)
            }
            Generator::Sheet { fraction, .. } if want == Phase::Solid => Some(*fraction),
            Generator::PerfusedBlock { solid_fraction, liquid_fraction, .. }
            | Generator::PerfusedMesh { solid_fraction, liquid_fraction, .. } => {
                Some(if want == Phase::Solid { *solid_fraction } else { *liquid_fraction })
            }
            _ => None,
        })
        .reduce(f64::min)
}

/// Notes on a valid scenario that are not errors but usually a typing slip: a box (particles, a
/// wall or an emitter's inlet) whose edge falls within a tenth of a spacing short of a whole number of spacings. The
/// generator fills ⌊extent/Δx⌋ layers, centred, so an edge typed 0.0999 for 0.1 at Δx = 0.01 loses a
/// whole layer without a word — in a wall, a slot the liquid leaks through (it happened to
/// `oscillating_wall.ron`: edges rounded to four digits opened a 1.5Δx slot at the tank's corner).
/// `perfuse run`, `validate` and the viewer print them; boxes whose extent is meant to leave a
/// fraction of a spacing are unaffected below 0.9Δx.
pub fn warnings(s: &Scenario) -> Vec<String> {
    let d = (s.dimensions as usize).min(3);
    let (dx_l, dx_s) = (s.numerics.dx_liquid, s.numerics.dx_solid);
    let mut out = Vec::new();
    // a length to the nanometre, without float noise in the message
    let nm = |x: f64| (x * 1e9).round() / 1e9;
    let mut check = |what: String, min: [f64; 3], max: [f64; 3], dx: Option<f64>, sym: &str| {
        let Some(dx) = dx.filter(|x| x.is_finite() && *x > 0.0) else { return };
        for a in 0..d {
            let ext = max[a] - min[a];
            let r = ext / dx;
            if !(r.is_finite() && r >= 1.0) {
                continue;
            }
            let n = (r + 1e-6).floor();
            let short = 1.0 - (r - n);
            if short < 0.1 && short > 1e-6 {
                let axis = ["x", "y", "z"][a];
                out.push(format!(
                    "{what}: the box is {r:.4} {sym} long along {axis} ({sym} = {dx} m), so it gets {n} layers, not \
                     {m}: its edges are {gap:.3e} m short of {m} layers. Make max[{a}] − min[{a}] = {full} m for {m} \
                     layers (or {exact} m for {n})",
                    n = n as u64,
                    m = n as u64 + 1,
                    gap = short * dx,
                    full = nm((n + 1.0) * dx),
                    exact = nm(n * dx),
                ));
            }
        }
    };
    for (i, g) in s.particles.iter().enumerate() {
        match g {
            Generator::Box { phase, min, max, .. } => {
                let dx = if *phase == Phase::Liquid { dx_l } else { dx_s };
                check(format!("particles[{i}]"), *min, *max, dx, if *phase == Phase::Liquid { "Δx_l" } else { "Δx_s" });
            }
            Generator::PerfusedBlock { min, max, .. } => {
                check(format!("particles[{i}] (solid lattice)"), *min, *max, dx_s, "Δx_s");
                check(format!("particles[{i}] (liquid lattice)"), *min, *max, dx_l, "Δx_l");
            }
            _ => {}
        }
    }
    for (i, b) in s.boundaries.iter().enumerate() {
        if let Region::Box { min, max } = &b.shape
            && b.mould.is_none()
        {
            let sp = b.spacing.or(dx_s).or(dx_l);
            check(format!("boundaries[{i}] `{}`", b.name), *min, *max, sp, "Δx_b");
        }
    }
    for (i, e) in s.emitters.iter().enumerate() {
        if let Region::Box { min, max } = &e.region {
            check(format!("emitters[{i}] `{}`", e.name), *min, *max, dx_l, "Δx_l");
        }
    }
    out
}

fn phase_dx(p: Phase, dx_l: Option<f64>, dx_s: Option<f64>) -> f64 {
    match p {
        Phase::Liquid => dx_l.unwrap_or(1.0),
        Phase::Solid => dx_s.unwrap_or(1.0),
    }
}

fn check_box(f: &str, min: [f64; 3], max: [f64; 3], d: usize, s: &Scenario) -> Result<(), Problem> {
    Check::vec(&format!("{f}.min"), min)?;
    Check::vec(&format!("{f}.max"), max)?;
    for a in 0..d {
        if max[a] <= min[a] {
            return Err(Check::fail(
                format!("{f}.max[{a}]"),
                format!("{} is not above min {}", max[a], min[a]),
                "give max > min on every axis",
            ));
        }
        let eps = 1e-9 * (s.domain.max[a] - s.domain.min[a]);
        if min[a] < s.domain.min[a] - eps || max[a] > s.domain.max[a] + eps {
            return Err(Check::fail(
                f,
                format!("extends outside the domain on axis {a}"),
                "keep generators inside `domain`",
            ));
        }
    }
    Ok(())
}

/// The springs of `ligaments`: regions as any region, a solid to hold, and an explicit step that
/// resolves the spring and its dashpot at the largest step the run may take.
fn check_ligaments(s: &Scenario, lig: &super::Ligaments) -> Result<(), Problem> {
    if s.solid.is_none() {
        return Err(Check::fail(
            "ligaments",
            "ligaments hold solid particles, but there is no solid",
            "remove it or add solid particles",
        ));
    }
    if lig.regions.is_empty() {
        return Err(Check::fail(
            "ligaments.regions",
            "no attachment region is given",
            "list at least one region, e.g. [Sphere(centre: (0, 0, 0), radius: 0.01)], or remove ligaments",
        ));
    }
    for (i, r) in lig.regions.iter().enumerate() {
        check_region(&format!("ligaments.regions[{i}]"), r)?;
    }
    Check::range("ligaments.damping_ratio", lig.damping_ratio, 0.0, 10.0, "give ζ ≥ 0, e.g. 1 (critical)")?;
    // The explicit step resolves the spring (ωΔt ≤ 1) and the dashpot (2ζωΔt ≤ 1).
    let dt = s.numerics.fixed_dt.unwrap_or(s.numerics.dt_max);
    let f_max = 1.0 / (2.0 * std::f64::consts::PI * dt * (2.0 * lig.damping_ratio).max(1.0));
    Check::positive("ligaments.frequency", lig.frequency, "give the springs' natural frequency in Hz, e.g. 10")?;
    if lig.frequency > f_max {
        return Err(Check::fail(
            "ligaments.frequency",
            format!(
                "{} Hz is too stiff for the largest step Δt = {dt} s (with ζ = {}: 2πf·Δt·max(1, 2ζ) must be ≤ 1)",
                lig.frequency, lig.damping_ratio
            ),
            format!("give at most {f_max:.0} Hz, or lower numerics.dt_max"),
        ));
    }
    Ok(())
}

/// A `numerics` field that only acts on a liquid under tension is set without `liquid_tension`.
fn needs_tension(n: &super::Numerics, field: &str) -> Result<(), Problem> {
    if n.liquid_tension {
        return Ok(());
    }
    Err(Check::fail(
        format!("numerics.{field}"),
        "is set but the liquid sustains no tension (liquid_tension: false), so it would never act",
        format!("add liquid_tension: true, or remove {field}"),
    ))
}

fn check_region(f: &str, r: &Region) -> Result<(), Problem> {
    match r {
        Region::Box { min, max } => {
            Check::vec(&format!("{f}.min"), *min)?;
            Check::vec(&format!("{f}.max"), *max)
        }
        Region::Sphere { centre, radius } => {
            Check::vec(&format!("{f}.centre"), *centre)?;
            Check::positive(&format!("{f}.radius"), *radius, "metres")
        }
    }
}

fn check_velocity(f: &str, v: &Option<InitialVelocity>) -> Result<(), Problem> {
    match v {
        None => Ok(()),
        Some(InitialVelocity::Uniform(u)) => Check::vec(&format!("{f}.velocity"), *u),
        Some(InitialVelocity::CantileverMode { root, length, amplitude, direction }) => {
            Check::finite(&format!("{f}.velocity.root"), *root)?;
            Check::positive(&format!("{f}.velocity.length"), *length, "metres")?;
            Check::finite(&format!("{f}.velocity.amplitude"), *amplitude)?;
            Check::vec(&format!("{f}.velocity.direction"), *direction)
        }
    }
}

/// Most regions of `numerics.liquid_tension_in` (the uniform block's `SimParams::tension`).
pub const MAX_TENSION_REGIONS: usize = 4;
/// Most emitters and sinks of a scenario (GPU table sizes, `sim::cpu::emit`).
pub const MAX_EMITTERS: usize = 8;
pub const MAX_SINKS: usize = 8;
/// Most pressure outlets (the uniform block's `SimParams::outlet`).
pub const MAX_OUTLETS: usize = 2;
/// Most emitter slots (lattice sites of all inlet regions together).
pub const MAX_EMITTER_SLOTS: usize = 4096;

/// Pressure outlets: boxes, at most `MAX_OUTLETS`, with a liquid and a sink to take what leaves the
/// buffer, finite pressures well below the liquid's stiffness, and a direction.
fn check_outlets(s: &Scenario) -> Result<(), Problem> {
    if s.outlets.len() > MAX_OUTLETS {
        return Err(Check::fail(
            "outlets",
            format!("{} outlets, at most {MAX_OUTLETS} are supported", s.outlets.len()),
            "merge the buffers into fewer boxes",
        ));
    }
    if s.outlets.is_empty() {
        return Ok(());
    }
    if s.liquid.is_none() || s.numerics.dx_liquid.is_none() {
        return Err(Check::fail(
            "outlets",
            "an outlet prescribes the liquid's pressure, but there is no `liquid` material or `numerics.dx_liquid`",
            "add a liquid material and numerics.dx_liquid, or remove the outlets",
        ));
    }
    if s.sinks.is_empty() {
        return Err(Check::fail(
            "outlets",
            "an outlet's buffer moves its liquid on, but there is no sink to take it",
            "add a sink just beyond each buffer (`sinks: [Sink(name: ..., region: Box(...))]`)",
        ));
    }
    for (i, o) in s.outlets.iter().enumerate() {
        let f = format!("outlets[{i}]");
        check_region(&format!("{f}.region"), &o.region)?;
        if !matches!(o.region, Region::Box { .. }) {
            return Err(Check::fail(
                format!("{f}.region"),
                "an outlet's buffer must be a Box",
                "give the buffer as Box(min: ..., max: ...) across the channel",
            ));
        }
        Check::range(&format!("{f}.pressure"), o.pressure, -1e7, 1e7, "a gauge pressure in Pa, e.g. -5000")?;
        let n = o.normal;
        if !n.iter().all(|c| c.is_finite()) || n.iter().map(|c| c * c).sum::<f64>() < 1e-12 {
            return Err(Check::fail(
                format!("{f}.normal"),
                format!("{n:?} is not a direction"),
                "give the direction toward the outlet's sink, e.g. (0.0, 0.0, 1.0)",
            ));
        }
        // the buffer's density ρ₀(1 + gauge/k) of (2.53) must stay a density
        if let Some(l) = &s.liquid {
            let k = l.stiffness.unwrap_or_else(|| l.density * l.sound_speed.unwrap_or(0.0).powi(2));
            if k > 0.0 && o.pressure <= -0.5 * k {
                return Err(Check::fail(
                    format!("{f}.pressure"),
                    format!("a suction of {} Pa expands the liquid (stiffness {k} Pa) by more than half", -o.pressure),
                    "give a suction well below the liquid's stiffness, or stiffen the liquid",
                ));
            }
        }
    }
    Ok(())
}

/// Emitters, sinks and the liquid capacity (issue 7): inlet regions that hold at least one lattice
/// site, finite non-negative flows, well-formed tables, a patient behind a hepatic inflow.
fn check_emitters(s: &Scenario, d: usize) -> Result<(), Problem> {
    if s.emitters.len() > MAX_EMITTERS {
        return Err(Check::fail(
            "emitters",
            format!("{} emitters, at most {MAX_EMITTERS} are supported", s.emitters.len()),
            "merge inlets into fewer regions",
        ));
    }
    if s.sinks.len() > MAX_SINKS {
        return Err(Check::fail(
            "sinks",
            format!("{} sinks, at most {MAX_SINKS} are supported", s.sinks.len()),
            "merge outlets into fewer regions",
        ));
    }
    if (!s.emitters.is_empty() || !s.sinks.is_empty()) && (s.liquid.is_none() || s.numerics.dx_liquid.is_none()) {
        let f = if s.emitters.is_empty() { "sinks" } else { "emitters" };
        return Err(Check::fail(
            f,
            "emitters and sinks move liquid particles, but there is no `liquid` material or `numerics.dx_liquid`",
            "add a liquid material and numerics.dx_liquid",
        ));
    }
    let dx_l = s.numerics.dx_liquid.unwrap_or(1.0);
    let mut slots = 0usize;
    for (i, e) in s.emitters.iter().enumerate() {
        let f = format!("emitters[{i}]");
        check_region(&format!("{f}.region"), &e.region)?;
        let n = super::generate::lattice_points(&e.region, dx_l, d).len();
        if n == 0 {
            return Err(Check::fail(
                format!("{f}.region"),
                format!("holds no lattice site of spacing Δx_l = {dx_l} m, so no particle can be placed"),
                "make the inlet at least Δx_l across on every axis",
            ));
        }
        slots += n;
        Check::vec(&format!("{f}.direction"), e.direction)?;
        let len2: f64 = e.direction.iter().take(d).map(|x| x * x).sum();
        if len2 <= 0.0 || !len2.is_finite() {
            return Err(Check::fail(
                format!("{f}.direction"),
                "is zero (in the simulated plane)",
                "give the direction the blood enters along, e.g. (1, 0, 0)",
            ));
        }
        if let Some(fr) = e.fraction {
            Check::range(&format!("{f}.fraction"), fr, 1e-3, 1.0, "a volume fraction n₀, e.g. 1 for free blood")?;
        }
        match &e.flow {
            Flow::Constant(q) => Check::range(&format!("{f}.flow"), *q, 0.0, 1.0, "m³/s, e.g. 1e-6 (1 mL/s)")?,
            Flow::Table { times, rates, period } => {
                let ft = format!("{f}.flow.times");
                if times.is_empty() || times.len() != rates.len() {
                    return Err(Check::fail(
                        ft,
                        format!("{} times for {} rates", times.len(), rates.len()),
                        "give one rate per time, at least one pair",
                    ));
                }
                if times.len() > super::FLOW_TABLE_MAX {
                    return Err(Check::fail(
                        ft,
                        format!("{} entries, at most {} are supported", times.len(), super::FLOW_TABLE_MAX),
                        "resample the table more coarsely",
                    ));
                }
                for (k, (t, q)) in times.iter().zip(rates).enumerate() {
                    Check::finite(&format!("{ft}[{k}]"), *t)?;
                    Check::range(&format!("{f}.flow.rates[{k}]"), *q, 0.0, 1.0, "m³/s, ≥ 0")?;
                    if k > 0 && *t <= times[k - 1] {
                        return Err(Check::fail(
                            format!("{ft}[{k}]"),
                            format!("{t} s does not follow {} s", times[k - 1]),
                            "list the times in increasing order",
                        ));
                    }
                }
                if let Some(p) = period {
                    Check::positive(&format!("{f}.flow.period"), *p, "seconds, e.g. one cardiac cycle 0.8")?;
                }
            }
            Flow::Hepatic => {
                if s.physiology.is_none() {
                    return Err(Check::fail(
                        format!("{f}.flow"),
                        "Hepatic flow comes from the patient model, but the scenario has no `physiology`",
                        "add physiology: Some(Physiology()) or give a Constant/Table flow",
                    ));
                }
            }
        }
    }
    if slots > MAX_EMITTER_SLOTS {
        return Err(Check::fail(
            "emitters",
            format!("the inlet regions hold {slots} lattice sites, at most {MAX_EMITTER_SLOTS} are supported"),
            "make the inlets smaller (a pipe cross-section one Δx_l thick)",
        ));
    }
    for (i, k) in s.sinks.iter().enumerate() {
        check_region(&format!("sinks[{i}].region"), &k.region)?;
    }
    check_outlets(s)?;
    if let Some(c) = s.liquid_capacity
        && (c == 0 || c as usize > MAX_PARTICLES)
    {
        return Err(Check::fail(
            "liquid_capacity",
            format!("{c} particles is out of range"),
            format!("give 1 … {MAX_PARTICLES}, at least the initial liquid"),
        ));
    }
    Ok(())
}
