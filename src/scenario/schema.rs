//! The RON scenario schema: what is simulated, in SI units (m, kg, s, Pa).
//!
//! Every struct denies unknown fields, so a misspelt field is an error that names it, never a silently
//! ignored value. Defaults are the values of SPEC.md §6; the shipped scenarios still state them
//! explicitly. Vectors are always written with three components `(x, y, z)`; 2-D scenarios put the
//! lattice in the z = 0 plane and ignore z.

use serde::{Deserialize, Serialize};

/// A 3-component vector in the scenario file.
pub type V3 = [f64; 3];

/// A whole scenario: materials, numerics, particles, boundaries, duration and outputs.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short identifier, used in output file names.
    pub name: String,
    /// One paragraph for people: what this scenario reproduces and where from.
    #[serde(default)]
    pub description: String,
    /// Spatial dimension, 2 (plane strain, lattice in z = 0) or 3.
    pub dimensions: u32,
    /// The simulated box and its periodic axes.
    pub domain: Domain,
    /// Body-force acceleration g [m/s²] applied to both phases (SPEC §3.11).
    #[serde(default)]
    pub gravity: V3,
    /// Liquid (blood) material; required when any liquid particle is generated.
    #[serde(default)]
    pub liquid: Option<Liquid>,
    /// Solid (tissue skeleton) material; required when any solid particle is generated.
    #[serde(default)]
    pub solid: Option<Solid>,
    /// Discretisation and stabilisation parameters.
    pub numerics: Numerics,
    /// Particle generators (lattices).
    pub particles: Vec<Generator>,
    /// Virtual boundary particle objects: walls, plates, tools (SPEC §4.1).
    #[serde(default)]
    pub boundaries: Vec<Boundary>,
    /// Regions whose solid particles are kinematic and held still (clamps, ligaments; SPEC §4.2).
    #[serde(default)]
    pub fixed_regions: Vec<Region>,
    /// Elastic ligament attachments: solid particles tied to their initial positions by damped springs
    /// (the organ's suspensory ligaments as elastic bands rather than rigid clamps). A particle inside
    /// a `fixed_regions` entry stays kinematic.
    #[serde(default)]
    pub ligaments: Option<Ligaments>,
    /// Glisson's capsule: surface detection and resolution enhancement of the solid (SPEC §4.5).
    #[serde(default)]
    pub membrane: Option<Membrane>,
    /// Regions emptied of tissue at set-up — solid, capsule and the perfused generators' blood — after
    /// the capsule is built and before the bond table is: where a needle was pushed into the specimen
    /// (SPEC §7.8). The capsule keeps no lining along the hole and no bond crosses it; boundary objects
    /// and plain liquid generators (`Box`, `Sphere`) fill it again (the needle's wall, a primed bore).
    #[serde(default)]
    pub cavities: Vec<Region>,
    /// Simulated time \[s\] of a run (after relaxation).
    pub duration: f64,
    /// Optional damped relaxation before t = 0 (SPEC §7.5).
    #[serde(default)]
    pub relaxation: Option<Relaxation>,
    /// Frames and probes written by `perfuse run`.
    #[serde(default)]
    pub output: Output,
    /// The patient: a closed-loop cardiovascular model that loses the blood leaving the organ.
    #[serde(default)]
    pub physiology: Option<Physiology>,
    /// Liquid sources: inlets that add particles at a prescribed volume flow (thesis §3.1.5, §4.2.4).
    #[serde(default)]
    pub emitters: Vec<Emitter>,
    /// Liquid sinks: regions that remove the liquid particles entering them (outlets, a syringe barrel).
    #[serde(default)]
    pub sinks: Vec<Sink>,
    /// Pressure outlets: buffers where the liquid's pressure is prescribed (a syringe's suction). Put
    /// a sink just beyond each buffer: buffer particles move on into it.
    #[serde(default)]
    pub outlets: Vec<Outlet>,
    /// Most liquid particles the run may hold (emitters stop at it, with a warning). Default: the
    /// initial liquid plus 20 000 when there are emitters.
    #[serde(default)]
    pub liquid_capacity: Option<u64>,
    /// Folder of the scenario file: relative mesh paths are resolved against it (set on load).
    #[serde(skip)]
    pub base_dir: Option<std::path::PathBuf>,
}

impl Scenario {
    /// The path of a mesh file named in the scenario (relative to the scenario file's folder).
    pub fn resolve(&self, file: &str) -> std::path::PathBuf {
        let p = std::path::Path::new(file);
        match &self.base_dir {
            Some(dir) if p.is_relative() => dir.join(p),
            _ => p.to_path_buf(),
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Domain {
    /// Lower corner \[m\].
    pub min: V3,
    /// Upper corner \[m\].
    pub max: V3,
    /// Periodic axes (x, y, z): particles leaving one side re-enter on the other (SPEC §4.3).
    #[serde(default)]
    pub periodic: [bool; 3],
}

/// Newtonian liquid (blood).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Liquid {
    /// Intrinsic density ρ₀ˡ [kg/m³].
    pub density: f64,
    /// Dynamic viscosity η [Pa·s] (2.50).
    pub viscosity: f64,
    /// Penalty stiffness k_sat of (2.53) \[Pa\]; give this or `sound_speed`, not both.
    #[serde(default)]
    pub stiffness: Option<f64>,
    /// Numerical sound speed c_l [m/s]; stiffness = ρ₀c² (SPEC D-5).
    #[serde(default)]
    pub sound_speed: Option<f64>,
    /// C₁ of the wicking pressure (3.5); 0 outside the wicking scenarios. `c1_from_equilibrium` gives it
    /// from the desired equilibrium liquid fraction instead.
    #[serde(default)]
    pub c1: f64,
    /// Sets C₁ = (1 − nˢ − nˡ_eq)/(nˢ nˡ_eq) from the equilibrium liquid fraction nˡ_eq of the porous solid
    /// of fraction nˢ (SPEC §3.4, D-9); give this or `c1`, not both.
    #[serde(default)]
    pub c1_from_equilibrium: Option<Equilibrium>,
    /// Liquid–void attraction strength γ [N/m] of (3.4): pulls the liquid toward unsaturated solid
    /// (wicking into a fabric, SPEC §3.12). 0: off.
    #[serde(default)]
    pub wicking: f64,
    /// Pairwise surface tension (3.3) (Tartakovsky–Meakin cohesion and adhesion); None: off.
    #[serde(default)]
    pub cohesion: Option<Cohesion>,
}

/// The equilibrium liquid fraction of (3.5): nˡ_eq = (1 − nˢ)/(1 + C₁nˢ).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Equilibrium {
    /// Volume fraction nˢ of the porous solid (the fabric's `fraction`).
    pub solid_fraction: f64,
    /// Desired liquid fraction nˡ_eq at which the modified liquid pressure (3.5) vanishes.
    pub liquid_fraction: f64,
}

impl Equilibrium {
    /// C₁ = (1 − nˢ − nˡ_eq)/(nˢ nˡ_eq) (SPEC §3.4).
    pub fn c1(&self) -> f64 {
        (1.0 - self.solid_fraction - self.liquid_fraction) / (self.solid_fraction * self.liquid_fraction)
    }
}

/// Strengths \[N\] of the pairwise surface-tension force (3.3), s_ij cos(πr/(2R_l)) toward the neighbour.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Cohesion {
    /// s_ll between two liquid particles (cohesion).
    pub liquid: f64,
    /// s_lb between a liquid particle and a wall/plate particle (adhesion); it sets the contact angle.
    #[serde(default)]
    pub boundary: f64,
}

/// Hyperelastic porous solid (tissue skeleton).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Solid {
    /// Intrinsic density ρ₀ˢ [kg/m³].
    pub density: f64,
    /// Mooney–Rivlin C10 \[Pa\] (2.14).
    pub c10: f64,
    /// Mooney–Rivlin C01 \[Pa\] (2.14).
    pub c01: f64,
    /// Structural stiffness k_s of (2.52) \[Pa\].
    pub k_s: f64,
    /// Solid volume fraction at perfused equilibrium nˢ_sat of (2.52).
    pub n_sat: f64,
    /// Saturation stiffness k_sat of (2.52) \[Pa\].
    pub k_sat: f64,
    /// Interphase friction coefficient K̄ [Pa·s/m²], K = (1 − nˢ)K̄ (2.17).
    #[serde(default)]
    pub friction: f64,
    /// Critical stretch λ_c of irreversible fracture (Alg. 2): a bond breaks beyond max(2h_s, λ_c r₀).
    /// None: the thesis criterion, beyond 2h_s, which breaks bonds born near 2h_s at a few per cent
    /// strain. Liver parenchyma fails at ≈ 30–50 % strain (λ_c ≈ 1.3–1.5).
    #[serde(default)]
    pub critical_stretch: Option<f64>,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Numerics {
    /// Lattice spacing of liquid particles Δx_l \[m\]; required when liquid is generated.
    #[serde(default)]
    pub dx_liquid: Option<f64>,
    /// Lattice spacing of solid particles Δx_s \[m\]; required when solid is generated.
    #[serde(default)]
    pub dx_solid: Option<f64>,
    /// h/Δx, 1 ≤ h/Δx ≤ 2 (thesis §2.2.4); default 1.3.
    #[serde(default = "d_h_over_dx")]
    pub h_over_dx: f64,
    /// Explicit smoothing length of the liquid \[m\] (overrides h_over_dx·Δx_l).
    #[serde(default)]
    pub h_liquid: Option<f64>,
    /// Explicit smoothing length of the solid \[m\] (overrides h_over_dx·Δx_s).
    #[serde(default)]
    pub h_solid: Option<f64>,
    /// Artificial viscosity (2.54)–(2.58).
    #[serde(default)]
    pub artificial_viscosity: ArtificialViscosity,
    /// Artificial stress (2.59)–(2.60).
    #[serde(default)]
    pub artificial_stress: ArtificialStress,
    /// XSPH ε̃ per phase (2.69).
    #[serde(default)]
    pub xsph: Xsph,
    /// Time-step factors of (2.70) and the friction bound (SPEC §5.3).
    #[serde(default)]
    pub cfl: Cfl,
    /// Smallest acceptable time step \[s\]: a run whose bound falls below it is reported as diverged.
    #[serde(default = "d_dt_min")]
    pub dt_min: f64,
    /// Largest time step \[s\].
    #[serde(default = "d_dt_max")]
    pub dt_max: f64,
    /// Fixed time step \[s\]; must not exceed the computed bound by more than 5 % (SPEC §5.3).
    #[serde(default)]
    pub fixed_dt: Option<f64>,
    /// Multiply the viscous term by κ_V (SPEC §2.5, D-7).
    #[serde(default = "d_true")]
    pub viscous_laplacian_normalisation: bool,
    /// Signal speed of the liquid [m/s]; default sqrt(k/ρ₀) (SPEC D-27).
    #[serde(default)]
    pub sound_speed_liquid: Option<f64>,
    /// Signal speed of the solid [m/s]; default includes the elastic wave speed (SPEC D-27).
    #[serde(default)]
    pub sound_speed_solid: Option<f64>,
    /// Multiply the liquid pressure-gradient terms by κ_S (the spiky kernel's lattice-moment correction,
    /// the pressure twin of κ_V; README: deviations from SPEC).
    #[serde(default = "d_true")]
    pub pressure_gradient_normalisation: bool,
    /// Let the liquid penalty pressure (2.53) go negative. Default false: pˡ = max(pˡ, 0), i.e. the liquid
    /// sustains no tension. With summation density (2.46) a free-surface particle misses part of its
    /// kernel support (nˡ ≈ 0.7 at a corner), which the linear penalty turns into tens of kPa of
    /// artificial tension that tears free surfaces apart (README: deviations from SPEC).
    #[serde(default)]
    pub liquid_tension: bool,
    /// With `liquid_tension`: let the pressure go negative only where the liquid sees a solid fraction
    /// nˢ below this (e.g. 0.05: the free blood of a primed syringe, not the blood perfusing tissue, where
    /// (2.53)'s negative side is an undersaturation, not a tension, and unclamped it sets the tissue's
    /// blood into the tensile instability: README, `syringe.ron`). Absent: everywhere.
    #[serde(default)]
    pub liquid_tension_below_ns: Option<f64>,
    /// With `liquid_tension`: regions (`Box` or `Sphere`, scenario coordinates; at most
    /// `MAX_TENSION_REGIONS`) where the pressure may go negative whatever nˢ — the tissue around a
    /// syringe's tip, so that the suction reaches into it while the blood by the capsule stays
    /// clamped. With regions and without `liquid_tension_below_ns`, tension acts only in the regions.
    #[serde(default)]
    pub liquid_tension_in: Vec<Region>,
    /// Ambient pressure p_a \[Pa\] (not in the thesis; README: deviations from SPEC): the liquid's pressure
    /// is p_a + (2.53) (still clamped at 0 without `liquid_tension`), so that a suction of up to p_a
    /// below ambient (an `outlets` buffer) is a lower pressure, not a tension that parts an SPH column.
    /// The capsule feels the blood's pressure less p_a (the ambient pressure outside it balances it).
    /// A liquid free surface feels p_a as an outward push, and it pushes blood through a one-particle
    /// capsule: use it where walls and buffers enclose the liquid (a sealed vessel), not on perfused
    /// tissue. Absent: 0, the thesis's pressure.
    #[serde(default)]
    pub ambient_pressure: Option<f64>,
    /// Speed [m/s] above which a particle counts as runaway (divergence); default 20·c_max.
    #[serde(default)]
    pub max_speed: Option<f64>,
    /// Hourglass control of the solid (not in the thesis; README: deviations from SPEC): a pair force
    /// over the intact bonds against the part of each bond's stretch that the best affine fit of the
    /// particle's bonds does not explain, with this dimensionless coefficient c (0 < c ≤ 10; 2 damps the
    /// zero-energy modes of a relaxing specimen). Absent: off, the thesis's operator.
    #[serde(default)]
    pub hourglass: Option<f64>,
    /// Monaghan's artificial pressure for a liquid under tension (not in the thesis; README: deviations
    /// from SPEC): liquid pairs with pˡ < 0 get the short-range repulsion (R_i + R_j)f_ij^n of (2.59)–(2.60)
    /// with R = ε|pˡ|/ρ² and f_ij = W_C(r; h_l)/W_C(Δx_l; h_l), which stops the pairing (tensile)
    /// instability of SPH under tension from stacking particles. Absent: off. Requires
    /// `liquid_tension` (a validation error otherwise).
    #[serde(default)]
    pub liquid_artificial_pressure: Option<ArtificialStress>,
    /// Renumber the liquid into the cell order of its neighbour list at every grid build
    /// (`grid_reorder`; issue 4), so that the neighbour walks gather velocities and densities from
    /// nearby memory as blood flows and mixes, and the GPU's walks read the liquid's own arrays as its
    /// list. Default true; false keeps the generated order (benchmarks of the gain; results
    /// differ by rounding only, as the order of each sum changes).
    #[serde(default = "d_true")]
    pub reorder_liquid: bool,
}

fn d_h_over_dx() -> f64 {
    1.3
}
fn d_dt_min() -> f64 {
    1e-9
}
fn d_dt_max() -> f64 {
    1e-3
}
fn d_true() -> bool {
    true
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ArtificialViscosity {
    /// α_d (2.55).
    pub alpha: f64,
    /// β_d (2.55).
    pub beta: f64,
    /// γ_d (2.54), regularises μ_ij.
    pub gamma: f64,
    /// Also apply to liquid–liquid pairs (SPEC D-20: off by default).
    pub liquid: bool,
}
impl Default for ArtificialViscosity {
    fn default() -> Self {
        ArtificialViscosity { alpha: 1.0, beta: 1.0, gamma: 0.01, liquid: false }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ArtificialStress {
    /// ε of (2.59); 0 disables the term.
    pub epsilon: f64,
    /// Exponent n of f_ij^n (2.60).
    pub exponent: u32,
}
impl Default for ArtificialStress {
    fn default() -> Self {
        ArtificialStress { epsilon: 0.3, exponent: 4 }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Xsph {
    /// ε̃ for solid particles.
    pub solid: f64,
    /// ε̃ for liquid particles.
    pub liquid: f64,
}
impl Default for Xsph {
    fn default() -> Self {
        Xsph { solid: 0.5, liquid: 0.0 }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Cfl {
    /// Overall factor C_Δt.
    pub factor: f64,
    /// Viscous factor of (2.70).
    pub viscous: f64,
    /// Sound-speed factor of (2.70) (divides h/(3c)).
    pub sound: f64,
    /// Force factor of (2.70) (multiplies sqrt(h/(3a))).
    pub force: f64,
    /// Explicit-friction factor (SPEC §5.3).
    pub friction: f64,
}
impl Default for Cfl {
    fn default() -> Self {
        Cfl { factor: 1.0, viscous: 0.125, sound: 0.25, force: 0.25, friction: 0.5 }
    }
}

/// Which particle set a generator fills.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
pub enum Phase {
    Liquid,
    Solid,
}

/// Initial velocity of generated particles.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub enum InitialVelocity {
    /// The same velocity [m/s] for every particle.
    Uniform(V3),
    /// First clamped–free bending mode of a beam along +x (SPEC §7.2):
    /// v(x) = amplitude · φ(x − root)/φ(length) along `direction`.
    CantileverMode { root: f64, length: f64, amplitude: f64, direction: V3 },
}

/// Particle lattices. All lattices are cell-centred: points at min + (k + ½)Δx, centred in the box when
/// the extent is not a whole number of spacings. The spacing is the phase's Δx from `numerics`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub enum Generator {
    /// A box of one phase (also a slab, a channel or a column). `fraction` is n₀ of (D-2).
    Box {
        phase: Phase,
        min: V3,
        max: V3,
        fraction: f64,
        #[serde(default)]
        velocity: Option<InitialVelocity>,
    },
    /// A ball of one phase.
    Sphere {
        phase: Phase,
        centre: V3,
        radius: f64,
        fraction: f64,
        #[serde(default)]
        velocity: Option<InitialVelocity>,
    },
    /// A single layer of solid particles (a fabric, SPEC §7.12): in 3-D the square lattice of spacing
    /// Δx_s on the plane z = centre.z spanning `size` = (x extent, y extent); in 2-D the row on
    /// y = centre.y spanning size.0. Its particle mass makes a liquid particle on the mid-plane see
    /// nˢ = `fraction` (m = nˢρ₀ˢ/Σ_sheet W6(·; R_×)); hold it with a `fixed_regions` entry.
    Sheet { centre: V3, size: (f64, f64), fraction: f64 },
    /// A perfused block: a solid lattice and an interpenetrating liquid lattice filling the same box.
    PerfusedBlock { min: V3, max: V3, solid_fraction: f64, liquid_fraction: f64 },
    /// A perfused organ: both lattices filling a closed surface mesh (Wavefront OBJ or STL; a path
    /// relative to the scenario file), scaled and placed by `placement` (3-D only). The shipped liver
    /// is `../meshes/liver.obj` (generator: `cargo run --release --example gen_liver`).
    PerfusedMesh {
        file: String,
        #[serde(default)]
        placement: super::mesh::Placement,
        solid_fraction: f64,
        liquid_fraction: f64,
    },
}

/// How a boundary object moves (SPEC §4.1: analytic x_b(t), v_b(t)).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub enum Motion {
    Static,
    /// Constant velocity [m/s] between `start` and `stop` \[s\]; at rest outside.
    Translate {
        velocity: V3,
        #[serde(default)]
        start: f64,
        #[serde(default)]
        stop: Option<f64>,
    },
    /// x_b(t) = x_b(0) + amplitude · sin(2πf t + phase).
    Oscillate {
        amplitude: V3,
        frequency: f64,
        #[serde(default)]
        phase: f64,
    },
}

/// Density and pressure a boundary particle shows to material particles (SPEC §4.1, D-23).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub enum PressureMode {
    /// ρ_b := ρ_i, p_b := max(p_i, 0): purely repulsive.
    Mirror,
    /// Constant ρ_b [kg/m³] and p_b \[Pa\] (syringe suction).
    Prescribed { density: f64, pressure: f64 },
}

/// A region of space.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub enum Region {
    Box { min: V3, max: V3 },
    Sphere { centre: V3, radius: f64 },
}

/// A rigid object of virtual boundary particles filling `shape` on a lattice of spacing Δx_b.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Boundary {
    pub name: String,
    /// Filled with a cell-centred lattice; make it at least R thick (3 layers at R = 2.6Δx).
    pub shape: Region,
    /// Lattice spacing Δx_b \[m\]; default Δx of the solid if there is one, else of the liquid.
    #[serde(default)]
    pub spacing: Option<f64>,
    #[serde(default = "d_static")]
    pub motion: Motion,
    #[serde(default = "d_mirror")]
    pub pressure: PressureMode,
    /// How solid tissue slides on this object. `None` (default): SPEC §4.1's contact, whose artificial
    /// viscosity acts on the whole relative velocity and so drags sliding tissue with a speed- and
    /// resolution-dependent numerical friction. `Some(μ)`: Coulomb contact — the artificial viscosity
    /// damps only the velocity along the object's surface normal, and the tangential force is
    /// −μ|f_n| against the sliding, sticking below one step's worth of it (README: deviations from
    /// SPEC). Tissue on a wet instrument ~0.1–0.2, on a dry tray ~0.3–0.6; `Some(0.0)` is frictionless.
    #[serde(default)]
    pub friction: Option<f64>,
    /// Marks the object as a tool the viewer's user drives with the mouse (a kinematic body, SPEC §4.1).
    #[serde(default)]
    pub tool: Option<Tool>,
    /// A bed moulded to the tissue's underside: only the lattice points of `shape` beneath the
    /// generated solid (straight down along ĝ) are kept, so the organ rests on its whole lower face
    /// instead of on the top of a flat box (the abdominal organs under the liver). Static objects only;
    /// it has no contact projection (its shape is not its surface), the virtual particles alone hold the
    /// tissue, as SPEC §4.1 has it.
    #[serde(default)]
    pub mould: Option<Mould>,
}

/// How a moulded bed follows the tissue above it (`Boundary::mould`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Mould {
    /// Gap left between the bed and the nearest solid particle \[m\]: about Δx_s, so that the bed's top
    /// layer sits where the tissue's next lattice layer would. Closer, the bed's virtual particles
    /// crowd the tissue's lowest layer and their pressure lifts it (measured on `liver.ron`: at Δx_s/2
    /// the tissue pinned by the ligaments above was squeezed to J ≈ 0.81 and its bonds tore).
    pub clearance: f64,
    /// Thickness of the bed beneath the tissue's lower face \[m\]; at least the support radius R so
    /// that tissue at its surface sees a full kernel of boundary particles.
    pub depth: f64,
}

/// What a user-driven boundary object is: the viewer maps mouse input to `MoveObject` /
/// `PlaceObject` + `SetBoundaryMotion` commands on it (scalpel and indenter follow the cursor at up to
/// `max_speed`; a projectile is fired along the view ray at `max_speed`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Tool {
    pub kind: ToolKind,
    /// Largest tool speed [m/s]; keep it below the sound speeds' tenth (numerics.sound_speed_*).
    pub max_speed: f64,
    /// Scalpel only (a `Box`): also break every bond whose segment crosses the blade's mid-plane
    /// rectangle (across the box's thinnest axis) — SPEC §4.6 option `blade_cut`, D-25. Off, the blade
    /// separates tissue only through the thesis's distance criterion (it may merely push the organ).
    #[serde(default)]
    pub blade_cut: bool,
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
pub enum ToolKind {
    Scalpel,
    Indenter,
    Projectile,
}

impl ToolKind {
    pub fn name(self) -> &'static str {
        match self {
            ToolKind::Scalpel => "scalpel",
            ToolKind::Indenter => "indenter",
            ToolKind::Projectile => "projectile",
        }
    }
}
fn d_static() -> Motion {
    Motion::Static
}
fn d_mirror() -> PressureMode {
    PressureMode::Mirror
}

/// An inlet (a vessel's stump, a pipe's end): a buffer region whose liquid moves as a kinematic body
/// at the inflow velocity u(t) = Q(t)·L/(N·V_p) along `direction` (N lattice sites of spacing Δx_l in
/// `region`, L the region's depth along `direction`, V_p = m/ρ₀ the volume of a particle), so the
/// buffer carries exactly the volume flow Q(t) into the domain; new particles are placed on its free
/// lattice sites ("slots") as the volume account reaches V_p. A slot with a liquid particle closer than
/// 0.5Δx_l (SPEC §4.4) is skipped, so particles are never placed on each other (volume that finds no free slot is
/// kept as a backlog and placed as slots free up). Close the region's back with a wall, as a real
/// pipe is closed upstream.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Emitter {
    pub name: String,
    pub region: Region,
    /// Direction of the inflow (normalised; need not be unit length, must not be zero).
    pub direction: V3,
    /// Volume flow of liquid [m³/s] (each particle carries the volume m/ρ₀; in 2-D m²/s per unit depth).
    pub flow: Flow,
    /// Rest volume fraction n₀ of the new particles (their mass is n₀ρ₀/S_W, as generated liquid):
    /// default the liquid fraction of the scenario's liquid generators, 1 when there are none.
    #[serde(default)]
    pub fraction: Option<f64>,
}

/// Volume flow of an emitter.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub enum Flow {
    /// Constant flow [m³/s].
    Constant(f64),
    /// Piecewise-linear in time: `rates[k]` [m³/s] at `times[k]` \[s\] (increasing; held constant
    /// outside), repeating with `period` \[s\] when given (e.g. one cardiac cycle).
    Table {
        times: Vec<f64>,
        rates: Vec<f64>,
        #[serde(default)]
        period: Option<f64>,
    },
    /// The patient's hepatic arterial flow (`physiology`), divided by its `volume_scale`.
    Hepatic,
}

/// A sink: liquid particles inside `region` are removed at the end of each step.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Sink {
    pub name: String,
    pub region: Region,
}

/// A pressure outlet (an open boundary after Tafuni et al. 2018, first order; README: deviations
/// from SPEC): liquid particles inside the buffer `region` (a `Box`) carry the prescribed pressure
/// `numerics.ambient_pressure + pressure` and the density of pure liquid at it (2.53) for their
/// neighbours, feel no force and move along `normal` with the Shepard (W6-weighted) mean normal
/// velocity of the open liquid within R_l. The liquid next to the buffer is pulled (pressure < 0) or
/// pushed into it; a sink beyond the buffer removes what leaves. Unlike a `Prescribed` boundary under a
/// sink, the buffer fills the kernel of the liquid below it, so the outlet removes what arrives and no
/// more. Make the buffer at least 2R_l deep, so that the buffer particles the open liquid sees have
/// whole kernels.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Outlet {
    pub name: String,
    /// The buffer: a `Box` a few Δx_l deep, across the whole channel.
    pub region: Region,
    /// Gauge pressure \[Pa\] in the buffer (−5000: a syringe's suction).
    pub pressure: f64,
    /// Direction in which liquid leaves through the buffer, toward its sink (normalised; e.g. (0, 0, 1)).
    pub normal: V3,
}

/// Most entries of a flow table (GPU table size, `sim::cpu::emit::FLOW_MAX`).
pub const FLOW_TABLE_MAX: usize = 1024;

/// The cardiovascular model coupled to the organ (issue 7, `sim::physiology`): liquid that leaves the
/// solid body is removed from the circulating volume, multiplied by `volume_scale` (simulated m³ →
/// physiological m³; documented per scenario: a small or coarse organ stands for a larger bleeding one).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Physiology {
    /// Model parameters; every field defaults to the literature value (`sim::cardio`).
    #[serde(default)]
    pub cardio: crate::sim::cardio::CardioParams,
    /// Physiological volume per simulated volume of lost blood.
    #[serde(default = "d_one")]
    pub volume_scale: f64,
}
fn d_one() -> f64 {
    1.0
}

/// Membrane (Glisson's capsule), thesis §3.1.2–3.1.3, SPEC §4.5: solid particles whose neighbourhood
/// centre of mass is offset by more than `threshold`·Δx_s are membrane particles; each gets `count`
/// children on its tangent plane at `radius`·Δx_s (the parent's mass shared equally). Membrane particles
/// hold nˡ at 1 − nˢ_sat and are boundary particles for the liquid.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Membrane {
    /// δ_mem / Δx_s (default 0.5).
    pub threshold: f64,
    /// N_e, children per membrane particle (default 3: a four-fold surface count, SPEC D-24).
    pub count: u32,
    /// r_e / Δx_s (default 0.5).
    pub radius: f64,
    /// θ₀ \[rad\] of the first child (default π/4).
    pub angle: f64,
    /// Capsule stiffness: the membrane particles' C10 and C01 over the tissue's (default 1, the
    /// thesis's membrane of plain solid particles, §3.1.3). Glisson's capsule is a collagenous sheet far
    /// stiffer than the parenchyma; one particle layer Δx_s thick stands for a sheet tens of µm thick,
    /// so a ratio > 1 gives that layer a sheet stiffness of the capsule's order (README: deviations).
    #[serde(default = "unit_ratio")]
    pub stiffness: f64,
    /// The capsule's seal (default true; README: deviations from SPEC): liquid within a quarter of its
    /// spacing of an intact capsule particle's plane, or just beyond it, cannot move outward through
    /// it (`forces::capsule_seal_pair`). `false`: the thesis's capsule, which holds blood only by its mirror
    /// pressure, and seeps where that pressure is zero.
    #[serde(default = "yes")]
    pub seal: bool,
    /// The capsule's ghost sites (default true; 3-D only; README: deviations from SPEC, "The capsule's
    /// ghost sites"): the tissue's and the blood's lattice sites that the organ's surface truncates
    /// within R of the body, carried by their nearest capsule particle and counted for the blood beneath
    /// it — nˢ, ρ and a wall pressure (`sim::ghosts`) — so that the blood at the capsule sees the
    /// generated fractions; the seal then acts at the organ's surface, Δx_s/2 beyond the capsule's
    /// particles. `false`: the thesis's capsule, a single layer of boundary particles (SPEC §4.1), beneath
    /// which the blood sees half a kernel of tissue and no penalty pressure.
    #[serde(default = "yes")]
    pub ghosts: bool,
}
fn unit_ratio() -> f64 {
    1.0
}
fn yes() -> bool {
    true
}
impl Default for Membrane {
    fn default() -> Self {
        Membrane {
            threshold: 0.5,
            count: 3,
            radius: 0.5,
            angle: std::f64::consts::FRAC_PI_4,
            stiffness: 1.0,
            seal: true,
            ghosts: true,
        }
    }
}

/// Elastic attachments: every solid particle whose lattice site lies in one of `regions` feels, besides
/// the tissue's forces, a damped spring to its initial (anchor) position X:
/// a = −ω²(x − X) − 2ζω v with ω = 2π·`frequency` (README: deviations from SPEC — the thesis holds its
/// hanging liver by kinematic particles, §4.2.6). A region of attached mass M_a is held by a total
/// stiffness ω²M_a, spread over its volume rather than concentrated on a rigid rim.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Ligaments {
    /// Attachment regions (the solid particles inside are tethered).
    pub regions: Vec<Region>,
    /// Natural frequency f \[Hz\] of one tethered particle on its spring alone.
    pub frequency: f64,
    /// Damping ratio ζ of the springs (1: critical; 0: undamped).
    #[serde(default = "default_ligament_damping")]
    pub damping_ratio: f64,
}

fn default_ligament_damping() -> f64 {
    1.0
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Relaxation {
    /// Relaxation time \[s\] before t = 0.
    pub duration: f64,
    /// Velocity damping ζ [1/s]: v ← v(1 − ζΔt).
    pub damping: f64,
    /// Gravity on the solid only (the liquid rides along through pressure and friction).
    #[serde(default)]
    pub gravity_solid_only: bool,
    /// Hold the suction until t = 0: while relaxing, boundaries with a `Prescribed` pressure show
    /// the mirror pressure instead, outlets prescribe nothing and sinks remove nothing
    /// (`Command::SetSuction(false)`), so that a primed syringe settles with its specimen and starts
    /// drawing at t = 0. Default false: sinks, outlets and prescribed pressures act during the
    /// relaxation too (a perfused organ settles perfused).
    #[serde(default)]
    pub hold_suction: bool,
}

impl Relaxation {
    /// The commands that start the relaxation (the clock at −duration, the damping on, the suction
    /// held if asked), in order: one list for the library, the viewer and the recorder.
    pub fn start_commands(&self) -> Vec<crate::sim::Command> {
        use crate::sim::Command;
        let mut c = vec![
            Command::SetTime(-self.duration),
            Command::SetDamping { damping: self.damping, gravity_solid_only: self.gravity_solid_only },
        ];
        if self.hold_suction {
            c.push(Command::SetSuction(false));
        }
        c
    }

    /// The commands that end it: the damping off, the suction released, the clock at t = 0.
    pub fn end_commands(&self) -> Vec<crate::sim::Command> {
        Relaxation::end(self.hold_suction)
    }

    /// [`Relaxation::end_commands`] of a relaxation that held the suction or not.
    pub fn end(hold_suction: bool) -> Vec<crate::sim::Command> {
        use crate::sim::Command;
        let mut c = vec![Command::SetDamping { damping: 0.0, gravity_solid_only: false }];
        if hold_suction {
            c.push(Command::SetSuction(true));
        }
        c.push(Command::SetTime(0.0));
        c
    }
}

/// Quantity averaged by a probe.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
pub enum Quantity {
    PositionX,
    PositionY,
    PositionZ,
    VelocityX,
    VelocityY,
    VelocityZ,
    Density,
    Pressure,
    SolidFraction,
    LiquidFraction,
}

/// A time series: the mean of `quantity` over the particles of `phase` inside `region` at t = 0.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Probe {
    pub name: String,
    pub phase: Phase,
    pub region: Region,
    pub quantity: Quantity,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq, Default)]
#[serde(deny_unknown_fields)]
pub struct Output {
    /// Simulated time between CSV frames \[s\]; none: only the final frame.
    #[serde(default)]
    pub frame_interval: Option<f64>,
    /// Probes sampled every frame (and at least 200 times per run) into `probes.csv`.
    #[serde(default)]
    pub probes: Vec<Probe>,
}

impl Region {
    pub fn contains(&self, p: [f64; 3], dims: u32) -> bool {
        match self {
            Region::Box { min, max } => (0..dims as usize).all(|a| p[a] >= min[a] && p[a] <= max[a]),
            Region::Sphere { centre, radius } => {
                let d2: f64 = (0..dims as usize).map(|a| (p[a] - centre[a]).powi(2)).sum();
                d2 <= radius * radius
            }
        }
    }
}
