//! Geometric contact with a bed moulded to the tissue (`Boundary::mould`). Such a bed has no shape the
//! contact projection of boxes and spheres could use (its particles fill only the part of its box under
//! the tissue), so its boundary particles held the tissue and the blood by their pressure alone: stretched
//! tissue (p < 0) was not pushed at all, and blood squeezed under an indenter seeped between the bed's
//! particles (10 liquid particles below the centres of the bed's top particles on the Δx = 7 mm liver,
//! indenter pressed to the bed). This module gives the bed a surface — a heightfield over its lattice columns, each column's
//! top the centre of its highest particle — that `object_contact` projects onto like a box face. The
//! pressure contact still holds the tissue about a smoothing length above those centres; the
//! projection only catches what passes it.
//!
//! One flat table of f32 serves both back-ends (the GPU binds it as `bed_table`, `integrate.wgsl`'s
//! `bed_contact` is the twin of [`bed_contact`]): per moulded bed a header of [`HEADER`] words, then the
//! column tops, row by row.

use crate::scenario::BoundaryObject;
use crate::sim::params::Params;
use glam::Vec3;

/// Header words: spacing, 1/spacing, first column's low edges on the two lateral axes, the bed's lower
/// face (height along up), the up axis, the two lateral axes (u32 bits), the up sign (±1), the column
/// counts on the two lateral axes (u32 bits).
pub const HEADER: usize = 11;

/// Top of a column with no bed particle: below anything.
pub const EMPTY: f32 = -3.0e38;

/// The moulded beds' heightfields and, per boundary object, where its own starts (0: none, else 1 + the
/// index of its header in `data`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BedTable {
    pub data: Vec<f32>,
    pub offsets: Vec<u32>,
}

impl BedTable {
    /// The table of `objects` in simulation coordinates. A bed's up axis is the axis of −gravity's
    /// largest component (moulding needs gravity, `scenario::validate`); its columns are its lattice's
    /// (spacing `BoundaryObject::spacing`).
    pub fn build(params: &Params, objects: &[BoundaryObject]) -> BedTable {
        let dims = params.dim.n();
        let mut t = BedTable { data: Vec::new(), offsets: Vec::with_capacity(objects.len()) };
        for o in objects {
            if !o.moulded || o.bed.is_empty() {
                t.offsets.push(0);
                continue;
            }
            let g = params.gravity;
            let up = (0..dims).max_by(|&a, &b| g[a].abs().total_cmp(&g[b].abs())).unwrap_or(1);
            let sign = if g[up] > 0.0 { -1.0f32 } else { 1.0 };
            let lateral: Vec<usize> = (0..3).filter(|&a| a != up).collect();
            let (la, lb) = (lateral[0], if dims == 3 { lateral[1] } else { 2 });
            let (sp, inv_sp) = (o.spacing as f32, 1.0 / o.spacing as f32);
            let pts: Vec<Vec3> = o.bed.iter().map(|p| params.to_sim(*p)).collect();
            let low = |a: usize| pts.iter().map(|p| p[a]).fold(f32::INFINITY, f32::min) - 0.5 * sp;
            let count = |a: usize, lo: f32| {
                let hi = pts.iter().map(|p| p[a]).fold(f32::NEG_INFINITY, f32::max);
                ((hi - lo) / sp).round() as u32
            };
            let (lo_a, lo_b) = (low(la), if dims == 3 { low(lb) } else { 0.0 });
            let (na, nb) = (count(la, lo_a).max(1), if dims == 3 { count(lb, lo_b).max(1) } else { 1 });
            let bottom = pts.iter().map(|p| sign * p[up]).fold(f32::INFINITY, f32::min) - 0.5 * sp;
            let start = t.data.len();
            t.offsets.push(start as u32 + 1);
            t.data.extend_from_slice(&[
                sp,
                inv_sp,
                lo_a,
                lo_b,
                bottom,
                f32::from_bits(up as u32),
                f32::from_bits(la as u32),
                f32::from_bits(lb as u32),
                sign,
                f32::from_bits(na),
                f32::from_bits(nb),
            ]);
            let tops = t.data.len();
            t.data.resize(tops + (na * nb) as usize, EMPTY);
            for p in &pts {
                // the column `bed_contact` finds for the point
                let ka = (((p[la] - lo_a) * inv_sp).floor() as i64).clamp(0, na as i64 - 1) as usize;
                let kb = if dims == 3 {
                    (((p[lb] - lo_b) * inv_sp).floor() as i64).clamp(0, nb as i64 - 1) as usize
                } else {
                    0
                };
                let h = &mut t.data[tops + kb * na as usize + ka];
                *h = h.max(sign * p[up]);
            }
        }
        t
    }

    /// The table as the GPU binds it (never empty: a zero-size binding is invalid).
    pub fn gpu_words(&self) -> Vec<f32> {
        if self.data.is_empty() { vec![0.0; HEADER] } else { self.data.clone() }
    }
}

/// Contact of a point `x` with the bed whose header starts at `off` in `t`: when `x` lies in one of the
/// bed's columns, below its top and above the bed's lower face, the nearest way out — up onto the
/// column's top, or sideways through a column face whose neighbour is empty or lower than `x` — as the
/// new position and the outward normal. Twin of `bed_contact` in `shaders/integrate.wgsl`, in the same
/// f32 operations.
pub fn bed_contact(t: &[f32], off: usize, x: Vec3, three_d: bool) -> Option<(Vec3, Vec3)> {
    let word = |k: usize| t[off + k].to_bits() as usize;
    let (sp, inv_sp, lo_a, lo_b, bottom) = (t[off], t[off + 1], t[off + 2], t[off + 3], t[off + 4]);
    let (up, la, lb, sign) = (word(5), word(6), word(7), t[off + 8]);
    let (na, nb) = (word(9) as i64, word(10) as i64);
    let ka = ((x[la] - lo_a) * inv_sp).floor();
    let kb = if three_d { ((x[lb] - lo_b) * inv_sp).floor() } else { 0.0 };
    if !(ka >= 0.0 && kb >= 0.0 && (ka as i64) < na && (kb as i64) < nb) {
        return None;
    }
    let (ka, kb) = (ka as i64, kb as i64);
    let top_of = |a: i64, b: i64| -> f32 {
        if a < 0 || b < 0 || a >= na || b >= nb { EMPTY } else { t[off + HEADER + (b * na + a) as usize] }
    };
    let h = sign * x[up];
    let top = top_of(ka, kb);
    if !(h > bottom && h < top) {
        return None;
    }
    let (mut best, mut axis, mut to, mut side) = (top - h, up, sign * top, sign);
    let mut lateral = |a: usize, k: i64, lo: f32, lower: f32, higher: f32| {
        let e0 = lo + k as f32 * sp;
        let e1 = lo + (k + 1) as f32 * sp;
        if x[a] - e0 < best && lower <= h {
            (best, axis, to, side) = (x[a] - e0, a, e0, -1.0);
        }
        if e1 - x[a] < best && higher <= h {
            (best, axis, to, side) = (e1 - x[a], a, e1, 1.0);
        }
    };
    lateral(la, ka, lo_a, top_of(ka - 1, kb), top_of(ka + 1, kb));
    if three_d {
        lateral(lb, kb, lo_b, top_of(ka, kb - 1), top_of(ka, kb + 1));
    }
    let mut y = x;
    y[axis] = to;
    let mut n = Vec3::ZERO;
    n[axis] = side;
    Some((y, n))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3 × 1 row of columns (x), tops 0, 0.1 and empty; up +y.
    fn row() -> Vec<f32> {
        let b = |u: u32| f32::from_bits(u);
        let mut t = vec![0.1, 10.0, -0.15, -0.05, -0.25, b(1), b(0), b(2), 1.0, b(3), b(1)];
        t.extend_from_slice(&[0.0, 0.1, EMPTY]);
        t
    }

    #[test]
    fn a_point_in_a_column_goes_out_the_nearest_open_way() {
        let t = row();
        // in the low column, just under its top: up
        let (y, n) = bed_contact(&t, 0, Vec3::new(-0.1, -0.01, 0.0), true).expect("inside");
        assert_eq!((y, n), (Vec3::new(-0.1, 0.0, 0.0), Vec3::Y));
        // above the top, beside the column, below the bed or past its end: no contact
        assert!(bed_contact(&t, 0, Vec3::new(-0.1, 0.01, 0.0), true).is_none());
        assert!(bed_contact(&t, 0, Vec3::new(-0.1, -0.3, 0.0), true).is_none());
        assert!(bed_contact(&t, 0, Vec3::new(0.2, 0.05, 0.0), true).is_none());
        assert!(bed_contact(&t, 0, Vec3::new(-0.1, -0.01, 0.06), true).is_none());
        // in the high column near its face toward the empty one: sideways (+x)
        let (y, n) = bed_contact(&t, 0, Vec3::new(0.04, 0.0, 0.0), true).expect("inside");
        assert!((y.x - 0.05).abs() < 1e-6 && y.y == 0.0 && n == Vec3::X, "{y} {n}");
        // near its face toward the lower column, above that column's top: sideways (−x)
        let (y, n) = bed_contact(&t, 0, Vec3::new(-0.04, 0.05, 0.0), true).expect("inside");
        assert!((y.x + 0.05).abs() < 1e-6 && n == -Vec3::X, "{y} {n}");
        // ... but below that top the lower column blocks the near face: out through the far one (in
        // 2-D: the one-column-deep bed's z faces are nearer still)
        let (y, n) = bed_contact(&t, 0, Vec3::new(-0.04, -0.02, 0.0), false).expect("inside");
        assert!((y.x - 0.05).abs() < 1e-6 && n == Vec3::X, "{y} {n}");
        // near the top of the high column: up
        let (y, n) = bed_contact(&t, 0, Vec3::new(0.0, 0.08, 0.0), true).expect("inside");
        assert!((y.y - 0.1).abs() < 1e-6 && n == Vec3::Y, "{y} {n}");
    }
}
