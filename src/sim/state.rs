//! Particle state as read back from either back-end: the format of tests, CSV frames, statistics and
//! (later) replay keyframes. Positions are in simulation coordinates (relative to `Params::origin`).

use glam::{Mat3, Vec3};

/// Fields common to both phases, in ascending id order (`in_id_order`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PhaseState {
    pub id: Vec<u32>,
    pub pos: Vec<Vec3>,
    pub vel: Vec<Vec3>,
    /// Apparent density [kg/m³].
    pub rho: Vec<f32>,
    pub n_s: Vec<f32>,
    pub n_l: Vec<f32>,
    /// Isotropic penalty pressure \[Pa\].
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

    /// The same particles in ascending id order: the back-ends renumber the liquid by cell every step
    /// (`grid_reorder`), the state they read back is always in id order.
    pub fn in_id_order(self) -> PhaseState {
        if self.id.is_sorted() || self.id.len() != self.pos.len() {
            return self;
        }
        let mut order: Vec<usize> = (0..self.id.len()).collect();
        order.sort_unstable_by_key(|&k| self.id[k]);
        fn gather<T: Copy>(v: &[T], order: &[usize]) -> Vec<T> {
            if v.len() == order.len() { order.iter().map(|&k| v[k]).collect() } else { v.to_vec() }
        }
        PhaseState {
            id: gather(&self.id, &order),
            pos: gather(&self.pos, &order),
            vel: gather(&self.vel, &order),
            rho: gather(&self.rho, &order),
            n_s: gather(&self.n_s, &order),
            n_l: gather(&self.n_l, &order),
            p: gather(&self.p, &order),
            mass: gather(&self.mass, &order),
        }
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

    /// Sizes of the connected components of the solid by intact bonds (Alg. 2), largest first.
    /// Kinematic (fixed, ligament) particles are left out so that a clamp does not join the pieces
    /// it holds.
    pub fn solid_component_sizes(&self) -> Vec<usize> {
        self.solid_components().iter().map(|c| c.members.len()).collect()
    }

    /// The connected components of the solid by intact bonds (Alg. 2), largest first (ties by lowest
    /// member), without the kinematic particles; each knows whether an intact bond ties it to one of
    /// them (whether it still hangs from the ligament or clamp).
    pub fn solid_components(&self) -> Vec<SolidComponent> {
        let n = self.solid.len();
        let fixed =
            |i: usize| self.solid_extra.flags.get(i).is_some_and(|f| f & crate::scenario::SolidFlags::KINEMATIC != 0);
        let mut parent: Vec<usize> = (0..n).collect();
        fn root(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        let mut tied = vec![false; n];
        for (i, list) in self.solid_extra.bond_lists.iter().enumerate() {
            if fixed(i) {
                continue;
            }
            for &j in list {
                let j = j as usize;
                if j >= n {
                    continue;
                }
                if fixed(j) {
                    tied[i] = true;
                } else {
                    let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                    if a != b {
                        parent[a.max(b)] = a.min(b);
                    }
                }
            }
        }
        let mut by_root: Vec<Option<usize>> = vec![None; n];
        let mut comps: Vec<SolidComponent> = Vec::new();
        for i in (0..n).filter(|&i| !fixed(i)) {
            let r = root(&mut parent, i);
            let k = *by_root[r].get_or_insert_with(|| {
                comps.push(SolidComponent { members: Vec::new(), anchored: false });
                comps.len() - 1
            });
            comps[k].members.push(i);
            comps[k].anchored |= tied[i];
        }
        comps.sort_by(|a, b| b.members.len().cmp(&a.members.len()).then(a.members[0].cmp(&b.members[0])));
        comps
    }

    /// Liquid particles outside the solid body: those that see (almost) no solid, nˢ < 0.05 (inside the
    /// perfused tissue nˢ ≈ nˢ_sat; at its surface about half of that).
    pub fn liquid_outside(&self) -> usize {
        self.liquid.n_s.iter().filter(|&&n| n < LIQUID_OUTSIDE_NS).count()
    }

    /// Number of bonds broken since t = 0 (pairs).
    pub fn broken_bonds(&self) -> u64 {
        let init: u64 = self.solid_extra.bonds_initial.iter().map(|&b| b as u64).sum();
        let now: u64 = self.solid_extra.bonds.iter().map(|&b| b as u64).sum();
        (init - now.min(init)) / 2
    }
}

/// A connected piece of the solid ([`State::solid_components`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SolidComponent {
    /// Solid particle indices, ascending.
    pub members: Vec<usize>,
    /// An intact bond ties it to a kinematic (fixed) particle.
    pub anchored: bool,
}

/// nˢ below which a liquid particle counts as outside the solid ([`State::liquid_outside`]).
pub const LIQUID_OUTSIDE_NS: f32 = 0.05;

/// Smallest solid component counted in `solid_components` (a 2 × 2 × 2 block of lattice sites);
/// smaller pieces are fragments.
pub const MIN_COMPONENT: usize = 8;

/// Finite check used by invariants.
pub fn all_finite(v: &[Vec3]) -> bool {
    v.iter().all(|x| x.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain 0-1-2 and a pair 3-4 joined to it only through kinematic particle 5: two components
    /// (the clamp does not join them); then breaking bond 1-2 makes three.
    #[test]
    fn components_by_intact_bonds_without_kinematic_particles() {
        let mut s = State::default();
        s.solid.pos = vec![Vec3::ZERO; 6];
        s.solid_extra.flags = vec![0, 0, 0, 0, 0, crate::scenario::SolidFlags::KINEMATIC];
        s.solid_extra.bond_lists = vec![vec![1], vec![0, 2], vec![1, 5], vec![4, 5], vec![3], vec![2, 3]];
        assert_eq!(s.solid_component_sizes(), vec![3, 2]);
        let c = s.solid_components();
        assert_eq!((c[0].members.clone(), c[0].anchored), (vec![0, 1, 2], true));
        assert_eq!((c[1].members.clone(), c[1].anchored), (vec![3, 4], true));
        s.solid_extra.bond_lists = vec![vec![1], vec![0], vec![5], vec![4, 5], vec![3], vec![2, 3]];
        assert_eq!(s.solid_component_sizes(), vec![2, 2, 1]);
        let anchored: Vec<bool> = s.solid_components().iter().map(|c| c.anchored).collect();
        assert_eq!(anchored, vec![false, true, true], "0-1 hangs free once 1-2 broke");
    }
}
