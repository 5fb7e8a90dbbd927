//! Emitters and sinks (issue 7) — twin of `shaders/emit.wgsl`. The thesis fed the hepatic-artery flow
//! of its cardiovascular solver into the liver as new liquid particles (§3.1.5, §4.2.4, Fig. 3.7); here
//! an inlet adds particles at a prescribed volume flow Q(t) and a sink removes those that enter it.
//!
//! The inlet is a buffer region whose liquid moves as a kinematic body at u(t) = Q(t)·L/(N·V_p) along
//! the inlet direction (N slots, L the slot lattice's depth along it, V_p = m/ρ₀): the buffer then
//! carries the volume flow Q into the domain whatever the pressure ahead of it, the usual velocity
//! inlet of open-boundary SPH (e.g. Federico et al. 2012). [`emit_velocities`] sets u(tⁿ⁺¹) once Δt
//! is known; `integrate` gives every liquid particle inside an inlet that velocity and no acceleration.
//!
//! Once per step, after the advance to xⁿ⁺¹ and before the grids are built (SPEC §5.2 step 6):
//! 1. `emit_mark`: a slot (lattice site of an inlet) is blocked when a liquid particle that is not
//!    about to be sunk lies closer than [`BLOCK_FACTOR`]·Δx_l — no particle is placed on another;
//! 2. `emit_compact`: liquid inside a sink is removed; the others keep their order (ids stay sorted);
//! 3. `emit_apply`: each emitter adds Q(tⁿ⁺¹)Δt to its volume account and, while the account holds a
//!    particle's volume m/ρ₀, places one on the next free slot (round robin), with the inlet velocity,
//!    a⁰ = 0 (the corrector then gives it ½Δt a¹), up to the liquid capacity. Volume that finds no free
//!    slot stays in the account (the backlog) and is placed as slots free up.
//!
//! All of it runs in f32 in the same order as the WGSL, so both back-ends add and remove the same
//! particles (up to the rounding of Q·Δt, see the differential test).

use super::CpuState;
use super::forces::ObjectGeom;
use crate::scenario::{Flow, GeneratedParticles, Region};
use crate::sim::params::Params;
use glam::Vec3;

/// A slot is blocked by a liquid particle closer than this many Δx_l.
pub const BLOCK_FACTOR: f32 = 0.9;
/// Entries of one emitter's flow table on the GPU (`scenario::FLOW_TABLE_MAX`).
pub const FLOW_MAX: usize = crate::scenario::FLOW_TABLE_MAX;

/// Q(t): piecewise linear through (times, rates), held outside, repeating with `period` (> 0).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FlowTable {
    pub times: Vec<f32>,
    pub rates: Vec<f32>,
    /// 0: not periodic.
    pub period: f32,
}

impl FlowTable {
    /// The table of a scenario flow; `Hepatic` starts at zero until the patient driver sets it.
    pub fn from_flow(flow: &Flow) -> FlowTable {
        match flow {
            Flow::Constant(q) => FlowTable { times: vec![0.0], rates: vec![*q as f32], period: 0.0 },
            Flow::Table { times, rates, period } => FlowTable {
                times: times.iter().map(|&t| t as f32).collect(),
                rates: rates.iter().map(|&q| q as f32).collect(),
                period: period.unwrap_or(0.0) as f32,
            },
            Flow::Hepatic => FlowTable { times: vec![0.0], rates: vec![0.0], period: 0.0 },
        }
    }

    /// Q at time `t` [m³/s] (twin of `flow_at` in emit.wgsl).
    pub fn rate_at(&self, t: f32) -> f32 {
        let n = self.times.len().min(self.rates.len());
        if n == 0 {
            return 0.0;
        }
        let mut tt = t;
        if self.period > 0.0 {
            tt = t - self.period * (t / self.period).floor();
        }
        if tt <= self.times[0] {
            return self.rates[0];
        }
        if tt >= self.times[n - 1] {
            return self.rates[n - 1];
        }
        let (mut lo, mut hi) = (0usize, n - 1);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if self.times[mid] <= tt {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let w = (tt - self.times[lo]) / (self.times[hi] - self.times[lo]);
        self.rates[lo] + (self.rates[hi] - self.rates[lo]) * w
    }
}

/// One inlet at run time.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Emitter {
    pub name: String,
    /// Buffer region (simulation coordinates).
    pub region: ObjectGeom,
    /// Slot positions (simulation coordinates).
    pub slots: Vec<Vec3>,
    /// Unit inflow direction.
    pub dir: Vec3,
    /// Buffer speed per unit flow, L/(N·V_p) [1/m²].
    pub speed_per_flow: f32,
    /// Buffer velocity u(tⁿ⁺¹) of the current step [m/s].
    pub velocity: Vec3,
    pub mass: f32,
    /// Volume m/ρ₀ each particle carries \[m³\].
    pub volume: f32,
    pub flow: FlowTable,
    /// Volume owed to the flow and not yet placed \[m³\].
    pub acc: f32,
    /// Next slot of the round robin.
    pub cursor: u32,
    /// Particles added so far.
    pub count: u64,
}

/// Emitters, sinks and their totals (part of the evolving state: restored with it on divergence).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct EmitState {
    pub emitters: Vec<Emitter>,
    pub sinks: Vec<ObjectGeom>,
    pub capacity: usize,
    /// Id of the first emitted particle (ids of new particles are `id_base + emitted`).
    pub id_base: u32,
    pub emitted: u64,
    pub sunk: u64,
    /// An emitter had volume to place but the liquid capacity was full.
    pub capacity_reached: bool,
}

/// A region's geometry in simulation coordinates (boundary objects, inlets, sinks) (box [a, b] or sphere centre a, radius b.x).
pub fn region_geom(params: &Params, r: &Region) -> ObjectGeom {
    match r {
        Region::Box { min, max } => ObjectGeom { kind: 0, a: params.to_sim(*min), b: params.to_sim(*max) },
        Region::Sphere { centre, radius } => {
            ObjectGeom { kind: 1, a: params.to_sim(*centre), b: Vec3::new(*radius as f32, 0.0, 0.0) }
        }
    }
}

/// A boundary object's geometry: its shape's, or kind 2 ("no shape": no contact projection, no surface
/// normal, no ghost-velocity extrapolation) for a bed moulded to the tissue, whose particles fill only
/// part of its shape (`Boundary::mould`). The GPU back-end uploads the same table.
pub fn object_geom(params: &Params, o: &crate::scenario::BoundaryObject) -> ObjectGeom {
    let mut g = region_geom(params, &o.shape);
    if o.moulded {
        g.kind = 2;
    }
    g
}

/// Whether `x` lies in `g` (on the first two axes only in 2-D) — twin of `in_region` in emit.wgsl.
pub fn in_region(g: &ObjectGeom, x: Vec3, three_d: bool) -> bool {
    if g.kind == 0 {
        let inside_xy = x.x >= g.a.x && x.x <= g.b.x && x.y >= g.a.y && x.y <= g.b.y;
        inside_xy && (!three_d || (x.z >= g.a.z && x.z <= g.b.z))
    } else {
        let d = x - g.a;
        let mut r2 = d.x * d.x + d.y * d.y;
        if three_d {
            r2 += d.z * d.z;
        }
        r2 <= g.b.x * g.b.x
    }
}

impl EmitState {
    pub fn new(params: &Params, g: &GeneratedParticles) -> EmitState {
        let rho0 = params.rho0_l;
        EmitState {
            emitters: g
                .emitters
                .iter()
                .map(|e| Emitter {
                    name: e.name.clone(),
                    region: region_geom(params, &e.region),
                    slots: e.slots.iter().map(|s| params.to_sim(*s)).collect(),
                    dir: Vec3::new(e.direction[0] as f32, e.direction[1] as f32, e.direction[2] as f32),
                    speed_per_flow: (e.depth / (e.slots.len().max(1) as f64 * e.mass / f64::from(rho0))) as f32,
                    velocity: Vec3::ZERO,
                    mass: e.mass as f32,
                    volume: e.mass as f32 / rho0,
                    flow: FlowTable::from_flow(&e.flow),
                    acc: 0.0,
                    cursor: 0,
                    count: 0,
                })
                .collect(),
            sinks: g.sinks.iter().map(|r| region_geom(params, r)).collect(),
            capacity: g.liquid_capacity.max(g.liquid.pos.len()),
            id_base: g.liquid.pos.len() as u32,
            emitted: 0,
            sunk: 0,
            capacity_reached: false,
        }
    }

    pub fn is_active(&self) -> bool {
        !self.emitters.is_empty() || !self.sinks.is_empty()
    }

    fn in_sink(&self, x: Vec3, three_d: bool) -> bool {
        self.sinks.iter().any(|g| in_region(g, x, three_d))
    }
}

/// Buffer velocities u(t) of every inlet at `t` = tⁿ⁺¹ (twin of `batch_motion`'s inlet part).
pub fn emit_velocities(st: &mut CpuState, t: f64) {
    let t = t as f32;
    for em in &mut st.emit.emitters {
        let speed = em.flow.rate_at(t) * em.speed_per_flow;
        em.velocity = em.dir * speed;
    }
}

/// The buffer velocity of the first inlet containing `x`, if any (twin of `inlet_velocity` in
/// common.wgsl): such a particle moves with it, unaccelerated.
#[inline]
pub fn inlet_velocity(e: &EmitState, x: Vec3, three_d: bool) -> Option<Vec3> {
    e.emitters.iter().find(|em| in_region(&em.region, x, three_d)).map(|em| em.velocity)
}

/// Steps 1–3 of the module docs at tⁿ⁺¹ = `t_next` with this step's Δt.
pub fn emit_step(p: &Params, st: &mut CpuState, dt: f32, t_next: f64) {
    if !st.emit.is_active() {
        return;
    }
    let three_d = p.dim.n() == 3;
    let blocked = emit_mark(p, st, three_d);
    emit_compact(st, three_d);
    emit_apply(st, &blocked, dt, t_next as f32);
}

/// emit_mark: per slot (all emitters' slots in order), whether a particle that stays blocks it.
fn emit_mark(p: &Params, st: &CpuState, three_d: bool) -> Vec<bool> {
    let r = BLOCK_FACTOR * p.dx_liquid;
    let r2 = r * r;
    let e = &st.emit;
    let slots: Vec<Vec3> = e.emitters.iter().flat_map(|em| em.slots.iter().copied()).collect();
    let mut blocked = vec![false; slots.len()];
    if slots.is_empty() {
        return blocked;
    }
    for &x in &st.liquid.x {
        // a held suction has no sinks (the GPU's n_sinks = 0)
        if !st.suction_held && e.in_sink(x, three_d) {
            continue;
        }
        for (s, b) in slots.iter().zip(blocked.iter_mut()) {
            let d = x - *s;
            let mut d2 = d.x * d.x + d.y * d.y;
            if three_d {
                d2 += d.z * d.z;
            }
            if d2 < r2 {
                *b = true;
            }
        }
    }
    blocked
}

/// emit_compact: removes the liquid inside sinks, keeping the order of the rest.
fn emit_compact(st: &mut CpuState, three_d: bool) {
    if st.emit.sinks.is_empty() || st.suction_held {
        return;
    }
    let keep: Vec<bool> = st.liquid.x.iter().map(|&x| !st.emit.in_sink(x, three_d)).collect();
    let removed = keep.iter().filter(|k| !**k).count();
    if removed == 0 {
        return;
    }
    fn retain<T>(v: &mut Vec<T>, keep: &[bool]) {
        let mut k = keep.iter();
        v.retain(|_| *k.next().unwrap_or(&true));
    }
    let l = &mut st.liquid;
    retain(&mut l.id, &keep);
    retain(&mut l.x, &keep);
    retain(&mut l.v, &keep);
    retain(&mut l.m, &keep);
    retain(&mut l.rho, &keep);
    retain(&mut l.n_l, &keep);
    retain(&mut l.n_s, &keep);
    retain(&mut l.p, &keep);
    retain(&mut l.a, &keep);
    retain(&mut l.a0, &keep);
    retain(&mut l.vx, &keep);
    st.emit.sunk += removed as u64;
}

/// emit_apply: the emitters' volume accounts and the new particles.
fn emit_apply(st: &mut CpuState, blocked: &[bool], dt: f32, t: f32) {
    let e = &mut st.emit;
    let l = &mut st.liquid;
    let mut slot_start = 0usize;
    for em in e.emitters.iter_mut() {
        let q = em.flow.rate_at(t);
        em.acc += q * dt;
        let n_slots = em.slots.len() as u32;
        let mut tries = 0u32;
        while em.acc >= em.volume && tries < n_slots {
            if l.x.len() >= e.capacity {
                e.capacity_reached = true;
                break;
            }
            let s = em.cursor;
            em.cursor = (em.cursor + 1) % n_slots;
            tries += 1;
            if blocked[slot_start + s as usize] {
                continue;
            }
            l.id.push(e.id_base.wrapping_add(e.emitted as u32));
            l.x.push(em.slots[s as usize]);
            l.v.push(em.velocity);
            l.m.push(em.mass);
            l.rho.push(0.0);
            l.n_l.push(0.0);
            l.n_s.push(0.0);
            l.p.push(0.0);
            l.a.push(Vec3::ZERO);
            l.a0.push(Vec3::ZERO);
            l.vx.push(em.velocity);
            em.acc -= em.volume;
            em.count += 1;
            e.emitted += 1;
        }
        slot_start += em.slots.len();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flow_table_interpolates_holds_and_repeats() {
        let t = FlowTable { times: vec![0.0, 1.0, 2.0], rates: vec![0.0, 2.0, 1.0], period: 0.0 };
        assert_eq!(t.rate_at(-1.0), 0.0);
        assert_eq!(t.rate_at(0.5), 1.0);
        assert_eq!(t.rate_at(1.5), 1.5);
        assert_eq!(t.rate_at(3.0), 1.0);
        let p = FlowTable { period: 2.0, ..t };
        assert_eq!(p.rate_at(4.5), 1.0);
        assert!(FlowTable::default().rate_at(1.0) == 0.0);
    }

    #[test]
    fn regions_respect_the_dimension() {
        let b = ObjectGeom { kind: 0, a: Vec3::new(0.0, 0.0, 0.0), b: Vec3::new(1.0, 1.0, 0.0) };
        assert!(in_region(&b, Vec3::new(0.5, 0.5, 3.0), false));
        assert!(!in_region(&b, Vec3::new(0.5, 0.5, 3.0), true));
        let s = ObjectGeom { kind: 1, a: Vec3::ZERO, b: Vec3::new(1.0, 0.0, 0.0) };
        assert!(in_region(&s, Vec3::new(0.6, 0.6, 5.0), false));
        assert!(!in_region(&s, Vec3::new(0.6, 0.6, 0.6), true));
    }
}
