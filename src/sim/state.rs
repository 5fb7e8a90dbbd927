//! Particle state as read back from either back-end: the format of tests, CSV frames, statistics and
//! (later) replay keyframes. Positions are in simulation coordinates (relative to `Params::origin`).

use glam::{Mat3, Vec3};

/// Fields common to both phases, in particle-id order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PhaseState {
    pub id: Vec<u32>,
    pub pos: Vec<Vec3>,
    pub vel: Vec<Vec3>,
    /// Apparent density [kg/m³].
    pub rho: Vec<f32>,
    pub n_s: Vec<f32>,
    pub n_l: Vec<f32>,
    /// Isotropic penalty pressure [Pa].
    pub p: Vec<f32>,
    pub mass: Vec<f32>,
}

/// Solid-only fields.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SolidExtra {
    pub flags: Vec<u32>,
    pub def_grad: Vec<Mat3>,
    /// Intact bonds per particle now and at t = 0 (damage D = 1 − now/initial).
    pub bonds: Vec<u32>,
    pub bonds_initial: Vec<u32>,
    /// Intact bond partners of each particle, ascending.
    pub bond_lists: Vec<Vec<u32>>,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct BoundaryState {
    pub pos: Vec<Vec3>,
    pub object: Vec<u32>,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct State {
    pub t: f64,
    pub steps: u64,
    pub liquid: PhaseState,
    pub solid: PhaseState,
    pub solid_extra: SolidExtra,
    pub boundary: BoundaryState,
}

impl PhaseState {
    pub fn len(&self) -> usize {
        self.pos.len()
    }
    pub fn is_empty(&self) -> bool {
        self.pos.is_empty()
    }
    pub fn total_mass(&self) -> f64 {
        self.mass.iter().map(|&m| m as f64).sum()
    }
}

impl State {
    /// FNV-1a hash of every evolving field's bits: equal hashes mean bit-identical states.
    pub fn hash(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |bits: u32| {
            for b in bits.to_le_bytes() {
                h ^= b as u64;
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        };
        for set in [&self.liquid, &self.solid] {
            for v in set.pos.iter().chain(set.vel.iter()) {
                eat(v.x.to_bits());
                eat(v.y.to_bits());
                eat(v.z.to_bits());
            }
            for r in &set.rho {
                eat(r.to_bits());
            }
        }
        for f in &self.solid_extra.def_grad {
            for x in f.to_cols_array() {
                eat(x.to_bits());
            }
        }
        for l in &self.solid_extra.bond_lists {
            for &j in l {
                eat(j);
            }
        }
        eat(self.steps as u32);
        h
    }

    /// Number of intact bonds (pairs).
    pub fn intact_bonds(&self) -> u64 {
        self.solid_extra.bonds.iter().map(|&b| b as u64).sum::<u64>() / 2
    }

    /// Number of bonds broken since t = 0 (pairs).
    pub fn broken_bonds(&self) -> u64 {
        let init: u64 = self.solid_extra.bonds_initial.iter().map(|&b| b as u64).sum();
        let now: u64 = self.solid_extra.bonds.iter().map(|&b| b as u64).sum();
        (init - now.min(init)) / 2
    }
}

/// Finite check used by invariants.
pub fn all_finite(v: &[Vec3]) -> bool {
    v.iter().all(|x| x.is_finite())
}
