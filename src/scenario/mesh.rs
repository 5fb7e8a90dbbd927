//! Organ geometry: triangle surface meshes (OBJ, STL) → SPH particle sets.
//!
//! # Why this exists
//! Perfuse fills organs with solid (and fluid) SPH particles on a lattice of spacing Δx. Box and sphere
//! specimens are built in; real organs come as surface meshes exported from segmentation or modelling
//! tools, and those meshes are rarely perfect: several objects in one file, vertices duplicated along
//! seams, inside-out orientation, a few missing triangles. This module
//!
//! * loads OBJ (via `tobj`, all objects merged, faces fan-triangulated) and STL (via `stl_io`, ASCII and
//!   binary) into one indexed [`TriMesh`], welding bit-identical vertices ([`load_mesh`]);
//! * rejects what cannot be simulated with a message that names the file and says the fix
//!   ([`MeshError`], [`TriMesh::validate`]): unreadable, unparsable, empty, absurdly large (more than
//!   [`MAX_TRIANGLES`]), non-finite, flat, inside-out, or open beyond repair;
//! * places the mesh as the scenario says ([`Placement`]: scale or fit-to-size, XYZ Euler rotation,
//!   translation);
//! * decides which lattice points `offset + Δx·(i, j, k)` lie inside ([`sample_interior`]), with an inside
//!   test that tolerates small holes.
//!
//! # The inside test
//! The reference is the generalised winding number (GWN) of Jacobson et al. 2013,
//! w(p) = Σ_triangles Ω(p) / 4π, with each solid angle Ω from the formula of Van Oosterom & Strackee
//! ([`TriMesh::winding_number`]); a point is inside when w ≥ ½ ([`TriMesh::contains`]). On a closed,
//! outward-oriented mesh w is exactly 1 inside and 0 outside; a small hole only lowers w near the hole,
//! so the ½ threshold still classifies almost every point correctly. It costs O(triangles) per point, too
//! slow for 10⁵–10⁶ lattice points × 10⁴ triangles on two cores, so [`sample_interior`] uses it only where
//! a cheaper exact test cannot be trusted:
//!
//! 1. For each of the three axes, one ray per lattice line along that axis: the triangles are binned by
//!    lattice row, every (triangle, line) pair is tested with a watertight 2-D point-in-triangle test
//!    (edge functions computed in a canonical vertex order so a shared edge gives bit-identical values
//!    to both of its triangles, and ties broken by a half-plane rule, as GPU rasterisers do) and the
//!    signed crossings (+1 leaving, −1 entering) are sorted along the line. The integer winding number
//!    of each lattice point on the line is the sum of the signs of the crossings beyond it. On a closed
//!    mesh this is exact, also for lines through vertices and edges, and for overlapping components.
//! 2. A line whose signs do not sum to zero passed through a hole: its verdicts are *unknown*.
//! 3. A point whose verdict is known on at least two of its three axis lines, with all known verdicts
//!    agreeing, takes that verdict; every other point (two lines through holes, a point on the surface,
//!    disagreement) is decided by the GWN.
//!
//! On a closed mesh the GWN is evaluated only for points exactly on the surface (none, usually); on a
//! mesh with a few small holes only for the points whose lines pass through two holes or that sit where
//! axes disagree, so the cost stays near that of ray casting. A wrong answer needs two of the three axis
//! lines through a point to pass through holes so that their crossings still sum to zero *and* to agree
//! on the wrong answer, which small holes make vanishingly unlikely.
//!
//! # Validation rules ([`TriMesh::validate`])
//! In this order: no triangles → [`MeshError::Empty`]; more than the limit → [`MeshError::TooLarge`]; an
//! index past the vertex list → [`MeshError::InvalidIndex`]; a NaN/∞ coordinate → [`MeshError::NonFinite`].
//! Then topology on the welded mesh: an edge used by one triangle is a *boundary* edge, one used twice in
//! the same direction is *inconsistently oriented*, one used three or more times is *non-manifold*. A mesh
//! with no boundary and no inconsistent edge is closed. Otherwise it is probed: w is evaluated at the
//! cell centres of an m × m × m grid over its bounding box (m = 12, or less — at least 4 — so that
//! m³ × triangles ≤ 5·10⁷ solid angles). A probe with 0.1 < w < 0.9 is *ambiguous*. The mesh is **open
//! beyond repair** ([`MeshError::Open`]) when
//! * more than 5 % of its edges are boundary edges ([`OPEN_EDGE_LIMIT`]), or
//! * no probe is clearly inside (w ≥ 0.9), or
//! * more than 10 % of the probes with w > 0.1 are ambiguous ([`AMBIGUOUS_LIMIT`]).
//!
//! A few small holes pass (they leave w ≈ 1 almost everywhere inside); half a sphere, a single open quad or a
//! sphere with a quarter cut away do not. Finally a mesh that encloses (almost) no volume, relative to its
//! bounding box, is [`MeshError::Degenerate`], and one with negative signed volume (normals pointing
//! inwards) is [`MeshError::Inverted`] — [`load_mesh`] already flips such files, so this only concerns
//! meshes built in code.

use rayon::prelude::*;
use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;

/// Largest number of triangles accepted from a file. Particle sampling at any Δx the simulator can run
/// (≥ 1 mm on an organ) needs far fewer; a bigger mesh only costs memory and time.
pub const MAX_TRIANGLES: usize = 2_000_000;

/// Largest number of candidate lattice points (bounding box / Δx³) [`sample_interior`] considers.
pub const MAX_LATTICE_POINTS: usize = 50_000_000;

/// A mesh with more than this fraction of boundary edges is open beyond repair.
pub const OPEN_EDGE_LIMIT: f64 = 0.05;

/// A non-closed mesh with more than this fraction of ambiguous probes (0.1 < w < 0.9) among the probes
/// with w > 0.1 is open beyond repair.
pub const AMBIGUOUS_LIMIT: f64 = 0.10;

/// An indexed triangle mesh. Triangles are counter-clockwise seen from outside (outward normals).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// Errors of loading, validating, placing and sampling a mesh. Messages say what is wrong, then the fix,
/// and end with the file in brackets.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    #[error("cannot read mesh file: {source} — check the path and permissions [{path}]")]
    Io { path: String, source: std::io::Error },
    #[error("cannot write mesh file: {source} — check that the folder exists and is writable [{path}]")]
    Write { path: String, source: std::io::Error },
    #[error("cannot parse mesh file: {detail} — re-export it as Wavefront OBJ or STL (ASCII or binary) [{path}]")]
    Parse { path: String, detail: String },
    #[error(
        "unsupported mesh format `{extension}` — use a .obj or .stl file (convert it with Blender or MeshLab) [{path}]"
    )]
    UnsupportedFormat { path: String, extension: String },
    #[error("mesh has no triangles — export the surface as faces (not only points or lines) [{path}]")]
    Empty { path: String },
    #[error(
        "mesh has {triangles} triangles, more than the limit of {limit} — decimate it (Blender: Decimate \
         modifier; MeshLab: Quadric Edge Collapse Decimation); particle sampling needs far fewer [{path}]"
    )]
    TooLarge { path: String, triangles: usize, limit: usize },
    #[error(
        "triangle {triangle} refers to vertex {index}, but the mesh has only {vertices} vertices — fix the \
         face indices [{path}]"
    )]
    InvalidIndex { path: String, triangle: usize, index: u32, vertices: usize },
    #[error(
        "a vertex has a non-finite coordinate ({x}, {y}, {z}) — fix or delete that vertex in a mesh editor \
         and export again [{path}]"
    )]
    NonFinite { path: String, vertex: usize, x: f64, y: f64, z: f64 },
    #[error(
        "mesh is open beyond repair: {boundary_edges} of its {edges} edges lie on holes and {inconsistent_edges} \
         are inconsistently oriented; {detail} — close the holes and make the normals consistent (Blender: \
         3D-Print Toolbox ▸ Make Manifold, Mesh ▸ Normals ▸ Recalculate Outside; MeshLab: Close Holes) and \
         export again; a few small holes are tolerated [{path}]"
    )]
    Open { path: String, boundary_edges: usize, inconsistent_edges: usize, edges: usize, detail: String },
    #[error("mesh encloses no volume: {detail} — export a closed solid, not a sheet or a line [{path}]")]
    Degenerate { path: String, detail: String },
    #[error(
        "mesh is inside out (signed volume {volume:.6e} < 0) — flip its normals (Blender: Mesh ▸ Normals ▸ \
         Recalculate Outside) or call TriMesh::orient_outward [{path}]"
    )]
    Inverted { path: String, volume: f64 },
    #[error("invalid mesh placement: {detail} [{path}]")]
    Placement { path: String, detail: String },
    #[error("cannot sample the mesh interior: {detail}")]
    Lattice { detail: String },
}

/// What [`TriMesh::validate`] found about a mesh that passed.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeshReport {
    pub vertices: usize,
    pub triangles: usize,
    /// Distinct undirected edges.
    pub edges: usize,
    /// Edges used by exactly one triangle (hole rims).
    pub boundary_edges: usize,
    /// Edges used by two triangles in the same direction (inconsistent orientation).
    pub inconsistent_edges: usize,
    /// Edges used by three or more triangles.
    pub nonmanifold_edges: usize,
    /// Connected components (by shared vertices).
    pub components: usize,
    /// No boundary and no inconsistently oriented edge.
    pub closed: bool,
    /// Fraction of ambiguous winding-number probes (see the module docs); `None` when the mesh is closed
    /// and no probe was needed.
    pub ambiguous_fraction: Option<f64>,
    /// Signed volume (positive: outward normals), in mesh units³.
    pub volume: f64,
    /// Surface area, in mesh units².
    pub area: f64,
    pub bounds_min: [f64; 3],
    pub bounds_max: [f64; 3],
}

/// Where and how big the scenario wants the mesh. Applied in this order: optionally move the bounding-box
/// centre to the origin, scale, rotate about x then y then z (fixed axes, `R = Rz·Ry·Rx`), translate:
/// `p' = translate + R · (s · (p − c))`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Placement {
    /// Uniform scale (mesh units → metres, e.g. 0.001 for a mesh in millimetres). Negative mirrors the mesh
    /// (triangle orientation is then flipped so normals stay outward).
    pub scale: f64,
    /// When set, replaces `scale`: the mesh is scaled so its largest bounding-box extent is this long (m).
    pub fit_size: Option<f64>,
    /// Move the bounding-box centre to the origin before scaling and rotating.
    pub center: bool,
    /// Rotation angles about x, y, z in degrees.
    pub rotate_deg: [f64; 3],
    /// Translation in metres, applied last.
    pub translate: [f64; 3],
}

impl Default for Placement {
    fn default() -> Self {
        Placement { scale: 1.0, fit_size: None, center: false, rotate_deg: [0.0; 3], translate: [0.0; 3] }
    }
}

impl Placement {
    /// Checks the numbers; `origin` names the scenario file for the message.
    pub fn check(&self, origin: &str) -> Result<(), MeshError> {
        let bad = |detail: String| Err(MeshError::Placement { path: origin.to_string(), detail });
        if !(self.scale.is_finite() && self.scale != 0.0) {
            return bad(format!(
                "`scale` is {} — give a finite, non-zero factor (e.g. 0.001 for millimetres)",
                self.scale
            ));
        }
        if let Some(f) = self.fit_size
            && !(f.is_finite() && f > 0.0)
        {
            return bad(format!("`fit_size` is {f} — give the largest extent in metres, > 0, or leave it out"));
        }
        if !self.rotate_deg.iter().chain(self.translate.iter()).all(|v| v.is_finite()) {
            return bad("`rotate_deg` and `translate` must be finite numbers".to_string());
        }
        Ok(())
    }

    fn matrix(&self) -> [[f64; 3]; 3] {
        let [a, b, c] = self.rotate_deg.map(f64::to_radians);
        let (sa, ca) = a.sin_cos();
        let (sb, cb) = b.sin_cos();
        let (sc, cc) = c.sin_cos();
        let rx = [[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]];
        let ry = [[cb, 0.0, sb], [0.0, 1.0, 0.0], [-sb, 0.0, cb]];
        let rz = [[cc, -sc, 0.0], [sc, cc, 0.0], [0.0, 0.0, 1.0]];
        mat_mul(&rz, &mat_mul(&ry, &rx))
    }
}

fn mat_mul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

// ---------------------------------------------------------------------------------------------------------
// Small vector helpers.

#[inline]
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
#[inline]
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Solid angle of triangle (a, b, c) seen from the origin (Van Oosterom & Strackee 1983), positive when
/// the origin is behind the triangle (on the side its normal points away from).
#[inline]
fn solid_angle(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let (la, lb, lc) = (norm(a), norm(b), norm(c));
    let num = dot(a, cross(b, c));
    let den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
    2.0 * num.atan2(den)
}

/// Generalised winding number of `p` with respect to a triangle soup.
fn soup_winding(soup: &[[[f64; 3]; 3]], p: [f64; 3]) -> f64 {
    let mut sum = 0.0;
    for t in soup {
        sum += solid_angle(sub(t[0], p), sub(t[1], p), sub(t[2], p));
    }
    sum / (4.0 * std::f64::consts::PI)
}

impl TriMesh {
    /// Axis-aligned bounding box of the vertices (zeros for a mesh without vertices).
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        if self.vertices.is_empty() {
            return ([0.0; 3], [0.0; 3]);
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for v in &self.vertices {
            for a in 0..3 {
                lo[a] = lo[a].min(v[a]);
                hi[a] = hi[a].max(v[a]);
            }
        }
        (lo, hi)
    }

    fn tri(&self, t: &[u32; 3]) -> [[f64; 3]; 3] {
        [self.vertices[t[0] as usize], self.vertices[t[1] as usize], self.vertices[t[2] as usize]]
    }

    /// Triangles as coordinate triples, skipping any with an out-of-range index.
    fn soup(&self) -> Vec<[[f64; 3]; 3]> {
        let n = self.vertices.len();
        self.triangles.iter().filter(|t| t.iter().all(|&i| (i as usize) < n)).map(|t| self.tri(t)).collect()
    }

    /// Signed enclosed volume by the divergence theorem (positive when normals point outward).
    pub fn volume(&self) -> f64 {
        let n = self.vertices.len();
        self.triangles
            .iter()
            .filter(|t| t.iter().all(|&i| (i as usize) < n))
            .map(|t| {
                let [a, b, c] = self.tri(t);
                dot(a, cross(b, c))
            })
            .sum::<f64>()
            / 6.0
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        self.soup().iter().map(|[a, b, c]| 0.5 * norm(cross(sub(*b, *a), sub(*c, *a)))).sum()
    }

    /// Flips every triangle if the signed volume is negative; returns whether it did.
    pub fn orient_outward(&mut self) -> bool {
        if self.volume() < 0.0 {
            for t in &mut self.triangles {
                t.swap(1, 2);
            }
            true
        } else {
            false
        }
    }

    /// The mesh placed as `t` says (see [`Placement`]). Call [`Placement::check`] first: non-finite numbers
    /// give non-finite vertices, which [`TriMesh::validate`] then rejects.
    pub fn transformed(&self, t: &Placement) -> TriMesh {
        let (lo, hi) = self.bounds();
        let c = if t.center { [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])] } else { [0.0; 3] };
        let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        let s = match t.fit_size {
            Some(f) if extent > 0.0 => f / extent,
            _ => t.scale,
        };
        let r = t.matrix();
        let vertices = self
            .vertices
            .iter()
            .map(|v| {
                let q = sub(*v, c).map(|x| x * s);
                [0, 1, 2].map(|i| t.translate[i] + dot(r[i], q))
            })
            .collect();
        let mut triangles = self.triangles.clone();
        if s < 0.0 {
            for tri in &mut triangles {
                tri.swap(1, 2);
            }
        }
        TriMesh { vertices, triangles }
    }

    /// Generalised winding number at `p` (Jacobson, Kavan & Sorkine-Hornung 2013): the solid angles of all
    /// triangles (Van Oosterom & Strackee 1983) summed and divided by 4π. 1 inside and 0 outside a closed
    /// outward mesh, ½ on a face, and a smooth value in between near holes.
    pub fn winding_number(&self, p: [f64; 3]) -> f64 {
        let n = self.vertices.len();
        let mut sum = 0.0;
        for t in self.triangles.iter().filter(|t| t.iter().all(|&i| (i as usize) < n)) {
            let [a, b, c] = self.tri(t);
            sum += solid_angle(sub(a, p), sub(b, p), sub(c, p));
        }
        sum / (4.0 * std::f64::consts::PI)
    }

    /// Whether `p` is inside: winding number ≥ ½.
    pub fn contains(&self, p: [f64; 3]) -> bool {
        self.winding_number(p) >= 0.5
    }

    /// Checks the mesh against the rules in the module docs with the default [`MAX_TRIANGLES`]; `path` only
    /// names the source in messages.
    pub fn validate(&self, path: &Path) -> Result<MeshReport, MeshError> {
        self.validate_with_limit(path, MAX_TRIANGLES)
    }

    /// [`TriMesh::validate`] with another triangle limit.
    pub fn validate_with_limit(&self, path: &Path, limit: usize) -> Result<MeshReport, MeshError> {
        let shown = path.display().to_string();
        self.check_basic(&shown, limit)?;
        let topo = self.topology();
        let (lo, hi) = self.bounds();
        let volume = self.volume();
        let mut ambiguous_fraction = None;
        let closed = topo.boundary == 0 && topo.inconsistent == 0;
        if !closed {
            let open = |detail: String| MeshError::Open {
                path: shown.clone(),
                boundary_edges: topo.boundary,
                inconsistent_edges: topo.inconsistent,
                edges: topo.edges,
                detail,
            };
            let edge_fraction = topo.boundary as f64 / topo.edges.max(1) as f64;
            if edge_fraction > OPEN_EDGE_LIMIT {
                return Err(open(format!(
                    "{:.1} % hole edges is more than the {:.0} % tolerated",
                    100.0 * edge_fraction,
                    100.0 * OPEN_EDGE_LIMIT
                )));
            }
            let probe = self.probe();
            if probe.clearly_inside == 0 {
                return Err(open(format!(
                    "no probe point is clearly inside (winding number ≥ 0.9 at none of {} probes)",
                    probe.probes
                )));
            }
            let frac = probe.ambiguous as f64 / probe.inside_like.max(1) as f64;
            ambiguous_fraction = Some(frac);
            if frac > AMBIGUOUS_LIMIT {
                return Err(open(format!(
                    "{:.0} % of the probes inside have an ambiguous winding number (limit {:.0} %)",
                    100.0 * frac,
                    100.0 * AMBIGUOUS_LIMIT
                )));
            }
        }
        let extent = sub(hi, lo);
        let box_volume = extent[0] * extent[1] * extent[2];
        let max_extent = extent.iter().copied().fold(0.0, f64::max);
        if extent.iter().any(|&e| e <= 1e-9 * max_extent) || box_volume <= 0.0 {
            return Err(MeshError::Degenerate {
                path: shown,
                detail: format!("it is flat (bounding box {:.3e} × {:.3e} × {:.3e})", extent[0], extent[1], extent[2]),
            });
        }
        if volume.abs() <= 1e-6 * box_volume {
            return Err(MeshError::Degenerate {
                path: shown,
                detail: format!("signed volume {volume:.3e} against a bounding box of {box_volume:.3e}"),
            });
        }
        if volume < 0.0 {
            return Err(MeshError::Inverted { path: shown, volume });
        }
        Ok(MeshReport {
            vertices: self.vertices.len(),
            triangles: self.triangles.len(),
            edges: topo.edges,
            boundary_edges: topo.boundary,
            inconsistent_edges: topo.inconsistent,
            nonmanifold_edges: topo.nonmanifold,
            components: topo.components,
            closed,
            ambiguous_fraction,
            volume,
            area: self.area(),
            bounds_min: lo,
            bounds_max: hi,
        })
    }

    /// Empty, too large, bad index, non-finite.
    fn check_basic(&self, shown: &str, limit: usize) -> Result<(), MeshError> {
        if self.triangles.is_empty() || self.vertices.is_empty() {
            return Err(MeshError::Empty { path: shown.to_string() });
        }
        if self.triangles.len() > limit {
            return Err(MeshError::TooLarge { path: shown.to_string(), triangles: self.triangles.len(), limit });
        }
        let n = self.vertices.len();
        for (ti, t) in self.triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::InvalidIndex { path: shown.to_string(), triangle: ti, index, vertices: n });
            }
        }
        if let Some((vi, v)) = self.vertices.iter().enumerate().find(|(_, v)| !v.iter().all(|c| c.is_finite())) {
            return Err(MeshError::NonFinite { path: shown.to_string(), vertex: vi, x: v[0], y: v[1], z: v[2] });
        }
        Ok(())
    }

    fn topology(&self) -> Topology {
        // (undirected key, forward?) per half-edge, sorted so the uses of one edge are adjacent.
        let mut half: Vec<(u64, bool)> = self
            .triangles
            .iter()
            .flat_map(|t| {
                [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])].map(|(a, b)| {
                    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
                    ((u64::from(lo) << 32) | u64::from(hi), a < b)
                })
            })
            .collect();
        half.par_sort_unstable();
        let mut topo = Topology::default();
        let mut i = 0;
        while i < half.len() {
            let mut j = i + 1;
            while j < half.len() && half[j].0 == half[i].0 {
                j += 1;
            }
            topo.edges += 1;
            match j - i {
                1 => topo.boundary += 1,
                2 => {
                    if half[i].1 == half[i + 1].1 {
                        topo.inconsistent += 1;
                    }
                }
                _ => topo.nonmanifold += 1,
            }
            i = j;
        }
        // Connected components by union-find over vertices.
        let mut parent: Vec<u32> = (0..self.vertices.len() as u32).collect();
        fn find(parent: &mut [u32], mut x: u32) -> u32 {
            while parent[x as usize] != x {
                parent[x as usize] = parent[parent[x as usize] as usize];
                x = parent[x as usize];
            }
            x
        }
        for t in &self.triangles {
            let r0 = find(&mut parent, t[0]);
            for &v in &t[1..] {
                let r = find(&mut parent, v);
                if r != r0 {
                    parent[r as usize] = r0;
                }
            }
        }
        let mut used = vec![false; self.vertices.len()];
        for t in &self.triangles {
            for &v in t {
                used[v as usize] = true;
            }
        }
        topo.components =
            (0..self.vertices.len() as u32).filter(|&v| used[v as usize] && find(&mut parent, v) == v).count();
        topo
    }

    /// Winding-number probes on a grid of cell centres over the bounding box.
    fn probe(&self) -> Probe {
        let soup = self.soup();
        let (lo, hi) = self.bounds();
        let m = ((5.0e7 / soup.len().max(1) as f64).cbrt().floor() as usize).clamp(4, 12);
        let pts: Vec<[f64; 3]> = (0..m * m * m)
            .map(|n| {
                let ijk = [n / (m * m), (n / m) % m, n % m];
                [0, 1, 2].map(|a| lo[a] + (hi[a] - lo[a]) * (ijk[a] as f64 + 0.5) / m as f64)
            })
            .collect();
        let w: Vec<f64> = pts.par_iter().map(|&p| soup_winding(&soup, p)).collect();
        Probe {
            probes: w.len(),
            inside_like: w.iter().filter(|&&x| x > 0.1).count(),
            ambiguous: w.iter().filter(|&&x| x > 0.1 && x < 0.9).count(),
            clearly_inside: w.iter().filter(|&&x| x >= 0.9).count(),
        }
    }

    /// Writes a Wavefront OBJ file: `header` lines as `#` comments, then `v x y z` and 1-based `f a b c`.
    pub fn write_obj(&self, path: &Path, header: &str) -> Result<(), MeshError> {
        let err = |source| MeshError::Write { path: path.display().to_string(), source };
        let file = std::fs::File::create(path).map_err(err)?;
        let mut w = std::io::BufWriter::new(file);
        let mut body = || -> std::io::Result<()> {
            for line in header.lines() {
                if line.starts_with('#') {
                    writeln!(w, "{line}")?;
                } else {
                    writeln!(w, "# {line}")?;
                }
            }
            for v in &self.vertices {
                writeln!(w, "v {} {} {}", v[0], v[1], v[2])?;
            }
            for t in &self.triangles {
                writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
            }
            w.flush()
        };
        body().map_err(err)
    }

    /// Merges bit-identical vertices (−0 and +0 alike) and drops triangles that collapse to a point or a
    /// line by index. Returns the number of dropped triangles.
    pub fn weld(&mut self) -> usize {
        let mut map: HashMap<[u64; 3], u32> = HashMap::with_capacity(self.vertices.len());
        let mut remap = Vec::with_capacity(self.vertices.len());
        let mut vertices = Vec::with_capacity(self.vertices.len());
        for v in &self.vertices {
            let key = v.map(|c| (c + 0.0).to_bits());
            let id = *map.entry(key).or_insert_with(|| {
                vertices.push(*v);
                (vertices.len() - 1) as u32
            });
            remap.push(id);
        }
        let before = self.triangles.len();
        let n = remap.len();
        self.triangles = self
            .triangles
            .iter()
            .map(|t| t.map(|i| if (i as usize) < n { remap[i as usize] } else { i }))
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect();
        self.vertices = vertices;
        before - self.triangles.len()
    }
}

#[derive(Default)]
struct Topology {
    edges: usize,
    boundary: usize,
    inconsistent: usize,
    nonmanifold: usize,
    components: usize,
}

struct Probe {
    probes: usize,
    inside_like: usize,
    ambiguous: usize,
    clearly_inside: usize,
}

// ---------------------------------------------------------------------------------------------------------
// Loading.

/// Loads an OBJ or STL file (by extension, case-insensitive) with the default [`MAX_TRIANGLES`].
///
/// OBJ: every object and group is merged, polygons are fan-triangulated, points and lines are ignored,
/// materials are not read. STL: ASCII or binary, told apart by the binary size rule (84 + 50·n bytes), so
/// binary files whose header starts with `solid` load too. Bit-identical vertices are welded, triangles
/// that collapse by index are dropped, and a mesh with negative signed volume (normals inward) is flipped.
/// Checked here: readable, parsable, not empty, not too large, finite. Call [`TriMesh::validate`] (or use
/// [`load_and_validate`]) for the topology rules.
pub fn load_mesh(path: &Path) -> Result<TriMesh, MeshError> {
    load_mesh_with_limit(path, MAX_TRIANGLES)
}

/// [`load_mesh`] followed by [`TriMesh::validate`].
pub fn load_and_validate(path: &Path) -> Result<(TriMesh, MeshReport), MeshError> {
    let mesh = load_mesh(path)?;
    let report = mesh.validate(path)?;
    Ok((mesh, report))
}

/// [`load_mesh`] with another triangle limit (the count is taken before the file is parsed, so an absurdly
/// large file is refused without being loaded).
pub fn load_mesh_with_limit(path: &Path, limit: usize) -> Result<TriMesh, MeshError> {
    let shown = path.display().to_string();
    let extension = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
    let mut mesh = match extension.as_str() {
        "obj" => load_obj(path, &shown, limit)?,
        "stl" => load_stl(path, &shown, limit)?,
        _ => {
            let extension = if extension.is_empty() { "(none)".to_string() } else { format!(".{extension}") };
            return Err(MeshError::UnsupportedFormat { path: shown, extension });
        }
    };
    mesh.weld();
    mesh.check_basic(&shown, limit)?;
    mesh.orient_outward();
    Ok(mesh)
}

fn io_err(shown: &str) -> impl Fn(std::io::Error) -> MeshError + '_ {
    move |source| MeshError::Io { path: shown.to_string(), source }
}

fn load_obj(path: &Path, shown: &str, limit: usize) -> Result<TriMesh, MeshError> {
    // Count the triangles first (streaming), so a huge file is refused before it is parsed.
    let file = std::fs::File::open(path).map_err(io_err(shown))?;
    let mut reader = BufReader::new(file);
    let mut line = Vec::new();
    let mut count = 0usize;
    loop {
        line.clear();
        if reader.read_until(b'\n', &mut line).map_err(io_err(shown))? == 0 {
            break;
        }
        let mut words = line.split(|b| b.is_ascii_whitespace()).filter(|w| !w.is_empty());
        if words.next() == Some(b"f".as_slice()) {
            count += words.count().saturating_sub(2);
        }
    }
    if count > limit {
        return Err(MeshError::TooLarge { path: shown.to_string(), triangles: count, limit });
    }
    let options = tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true };
    let (models, _materials) = tobj::load_obj(path, &options).map_err(|e| {
        let detail = match e {
            tobj::LoadError::ReadError => "OBJ: not a text file (invalid UTF-8: binary or corrupted?)".to_string(),
            other => format!("OBJ: {other}"),
        };
        MeshError::Parse { path: shown.to_string(), detail }
    })?;
    let mut mesh = TriMesh::default();
    for model in &models {
        let base = mesh.vertices.len();
        let m = &model.mesh;
        mesh.vertices.extend(m.positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        let nv = m.positions.len() / 3;
        for t in m.indices.chunks_exact(3) {
            if let Some(&bad) = t.iter().find(|&&i| i as usize >= nv) {
                return Err(MeshError::Parse {
                    path: shown.to_string(),
                    detail: format!("object `{}` has a face with vertex index {} of {nv}", model.name, bad + 1),
                });
            }
            let off = |i: u32| (base + i as usize) as u32;
            mesh.triangles.push([off(t[0]), off(t[1]), off(t[2])]);
        }
    }
    Ok(mesh)
}

fn load_stl(path: &Path, shown: &str, limit: usize) -> Result<TriMesh, MeshError> {
    let parse = |detail: String| MeshError::Parse { path: shown.to_string(), detail };
    let mut file = std::fs::File::open(path).map_err(io_err(shown))?;
    let len = file.metadata().map_err(io_err(shown))?.len();
    let mut head = Vec::with_capacity(84);
    (&mut file).take(84).read_to_end(&mut head).map_err(io_err(shown))?;
    let starts_solid = head.trim_ascii_start().starts_with(b"solid");
    let announced =
        if head.len() == 84 { u64::from(u32::from_le_bytes([head[80], head[81], head[82], head[83]])) } else { 0 };
    let binary_size = 84 + 50 * announced;
    let binary_fits = head.len() == 84 && len >= binary_size && len < binary_size + 50;
    let bytes = if binary_fits || (!starts_solid && head.len() == 84) {
        if !binary_fits {
            return Err(parse(format!(
                "not an ASCII STL (no `solid` header) and not a binary STL (its header announces {announced} \
                 triangles = {binary_size} bytes, the file has {len} bytes)"
            )));
        }
        if announced as usize > limit {
            return Err(MeshError::TooLarge { path: shown.to_string(), triangles: announced as usize, limit });
        }
        let mut bytes = head;
        file.read_to_end(&mut bytes).map_err(io_err(shown))?;
        // stl_io takes a file starting with "solid " for ASCII; the 80-byte binary header is free text.
        bytes[..5].copy_from_slice(b"SOLID");
        bytes
    } else if starts_solid {
        let mut bytes = head;
        file.read_to_end(&mut bytes).map_err(io_err(shown))?;
        let facets = bytes.split(|&b| b == b'\n').filter(|l| l.trim_ascii_start().starts_with(b"facet")).count();
        if facets > limit {
            return Err(MeshError::TooLarge { path: shown.to_string(), triangles: facets, limit });
        }
        // stl_io wants "solid NAME"; some exporters write a bare "solid" line.
        let start = bytes.len() - bytes.trim_ascii_start().len();
        let first_end = bytes[start..].iter().position(|&b| b == b'\n').map_or(bytes.len(), |p| start + p);
        let mut fixed = b"solid mesh\n".to_vec();
        fixed.extend_from_slice(bytes.get(first_end + 1..).unwrap_or(&[]));
        fixed
    } else {
        return Err(parse(format!("only {len} bytes: neither an ASCII STL (`solid …`) nor a binary STL (≥ 84 bytes)")));
    };
    let mut cursor = std::io::Cursor::new(bytes);
    let reader = stl_io::create_stl_reader(&mut cursor).map_err(|e| parse(format!("STL: {e}")))?;
    let mut mesh = TriMesh::default();
    for (n, tri) in reader.enumerate() {
        let tri = tri.map_err(|e| parse(format!("STL triangle {}: {e}", n + 1)))?;
        if mesh.triangles.len() >= limit {
            return Err(MeshError::TooLarge { path: shown.to_string(), triangles: limit + 1, limit });
        }
        let base = mesh.vertices.len() as u32;
        mesh.vertices.extend(tri.vertices.iter().map(|v| v.0.map(f64::from)));
        mesh.triangles.push([base, base + 1, base + 2]);
    }
    Ok(mesh)
}

// ---------------------------------------------------------------------------------------------------------
// Lattice sampling.

/// Counters of one [`sample_interior_stats`] run.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SampleStats {
    /// Lattice points in the bounding box.
    pub candidates: usize,
    /// Points found inside.
    pub inside: usize,
    /// Points decided by the generalised winding number (the rest by ray crossings).
    pub winding_fallbacks: usize,
    /// Lattice lines (over the three axes) whose crossings did not sum to zero: they passed through a hole.
    pub open_lines: usize,
}

struct Lattice {
    off: [f64; 3],
    dx: f64,
    lo: [i64; 3],
    n: [usize; 3],
}

impl Lattice {
    #[inline]
    fn coord(&self, axis: usize, i: usize) -> f64 {
        self.off[axis] + self.dx * (self.lo[axis] + i as i64) as f64
    }
    #[inline]
    fn index(&self, ijk: [usize; 3]) -> usize {
        (ijk[0] * self.n[1] + ijk[1]) * self.n[2] + ijk[2]
    }
    /// 0-based index range (inclusive, widened by one for rounding) of lattice coordinates in [a, b].
    fn range(&self, axis: usize, a: f64, b: f64) -> Option<(usize, usize)> {
        let i0 = ((a - self.off[axis]) / self.dx).ceil() as i64 - self.lo[axis] - 1;
        let i1 = ((b - self.off[axis]) / self.dx).floor() as i64 - self.lo[axis] + 1;
        let i0 = i0.max(0);
        let i1 = i1.min(self.n[axis] as i64 - 1);
        (i0 <= i1).then_some((i0 as usize, i1 as usize))
    }
}

/// Lattice points `offset + dx·(i, j, k)` (integer i, j, k) inside `mesh`, sorted by (i, j, k) with k
/// fastest. Empty when `dx` or `offset` is not finite and positive, or the box holds more than
/// [`MAX_LATTICE_POINTS`]; [`try_sample_interior`] says why instead. See the module docs for the method.
pub fn sample_interior(mesh: &TriMesh, dx: f64, offset: [f64; 3]) -> Vec<[f64; 3]> {
    try_sample_interior(mesh, dx, offset).unwrap_or_default()
}

/// [`sample_interior`] with an error for a bad spacing or too many lattice points.
pub fn try_sample_interior(mesh: &TriMesh, dx: f64, offset: [f64; 3]) -> Result<Vec<[f64; 3]>, MeshError> {
    sample_interior_stats(mesh, dx, offset).map(|(points, _)| points)
}

/// [`try_sample_interior`] that also returns how the points were decided.
pub fn sample_interior_stats(
    mesh: &TriMesh,
    dx: f64,
    offset: [f64; 3],
) -> Result<(Vec<[f64; 3]>, SampleStats), MeshError> {
    if !(dx.is_finite() && dx > 0.0 && offset.iter().all(|o| o.is_finite())) {
        return Err(MeshError::Lattice {
            detail: format!("spacing Δx = {dx} and offset {offset:?} must be finite, Δx > 0 — fix the scenario"),
        });
    }
    let soup = mesh.soup();
    if soup.is_empty() {
        return Ok((Vec::new(), SampleStats::default()));
    }
    let (bmin, bmax) = mesh.bounds();
    let mut lo = [0i64; 3];
    let mut n = [0usize; 3];
    let mut total = 1.0f64;
    for a in 0..3 {
        let i0 = ((bmin[a] - offset[a]) / dx).ceil();
        let i1 = ((bmax[a] - offset[a]) / dx).floor();
        if !(i0.is_finite() && i1.is_finite()) || i1 < i0 {
            return Ok((Vec::new(), SampleStats::default()));
        }
        total *= i1 - i0 + 1.0;
        if total > MAX_LATTICE_POINTS as f64 {
            return Err(MeshError::Lattice {
                detail: format!(
                    "Δx = {dx} gives more than {MAX_LATTICE_POINTS} lattice points in the mesh's bounding box \
                     {bmin:?} – {bmax:?} — increase Δx or check the mesh scale (a mesh in mm needs scale 0.001)"
                ),
            });
        }
        lo[a] = i0 as i64;
        n[a] = (i1 - i0) as usize + 1;
    }
    let lat = Lattice { off: offset, dx, lo, n };
    let count = n[0] * n[1] * n[2];
    let mut stats = SampleStats { candidates: count, ..SampleStats::default() };
    let mut axes = Vec::with_capacity(3);
    for axis in [2usize, 0, 1] {
        let (v, open) = axis_verdicts(&soup, &lat, axis);
        stats.open_lines += open;
        axes.push(v);
    }
    // A point is decided by the rays when at least two axes know (their line's crossings sum to zero) and
    // all that know agree; otherwise (a point near a hole, on the surface, or disagreement) by the GWN.
    let mut verdict: Vec<u8> = (0..count)
        .into_par_iter()
        .map(|i| {
            let (mut known, mut inside) = (0, 0);
            for v in &axes {
                if v[i] != UNKNOWN {
                    known += 1;
                    inside += usize::from(v[i] == INSIDE);
                }
            }
            if known >= 2 && (inside == 0 || inside == known) { u8::from(inside > 0) } else { UNKNOWN }
        })
        .collect();
    drop(axes);
    let unknown: Vec<usize> = (0..count).filter(|&i| verdict[i] == UNKNOWN).collect();
    stats.winding_fallbacks = unknown.len();
    let decided: Vec<u8> = unknown
        .par_iter()
        .map(|&idx| {
            let ijk = [idx / (n[1] * n[2]), (idx / n[2]) % n[1], idx % n[2]];
            let p = [0, 1, 2].map(|a| lat.coord(a, ijk[a]));
            u8::from(soup_winding(&soup, p) >= 0.5)
        })
        .collect();
    for (&idx, &d) in unknown.iter().zip(&decided) {
        verdict[idx] = d;
    }
    let mut points = Vec::new();
    for i in 0..n[0] {
        for j in 0..n[1] {
            for k in 0..n[2] {
                if verdict[lat.index([i, j, k])] == INSIDE {
                    points.push([lat.coord(0, i), lat.coord(1, j), lat.coord(2, k)]);
                }
            }
        }
    }
    stats.inside = points.len();
    Ok((points, stats))
}

const INSIDE: u8 = 1;
const UNKNOWN: u8 = 2;

#[inline]
fn orient2(a: [f64; 2], b: [f64; 2], q: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0])
}

/// `orient2(a, b, q)` evaluated in a canonical vertex order, so both triangles of a shared edge get exactly
/// opposite values.
#[inline]
fn edge_fn(a: [f64; 2], b: [f64; 2], q: [f64; 2]) -> f64 {
    if (a[0], a[1]) <= (b[0], b[1]) { orient2(a, b, q) } else { -orient2(b, a, q) }
}

/// Tie rule for a point exactly on an edge, by the edge's counter-clockwise direction: exactly one of `d`
/// and `−d` is included, so a point on a shared edge (or vertex) belongs to exactly one side.
#[inline]
fn tie_included(d: [f64; 2]) -> bool {
    d[1] > 0.0 || (d[1] == 0.0 && d[0] < 0.0)
}

/// Crossing of the line {(b, c) = q} along `axis` with triangle `t`: the coordinate along the axis and
/// the sign (+1 when the triangle's normal points along +axis).
#[inline]
fn ray_hit(t: &[[f64; 3]; 3], axis: usize, q: [f64; 2]) -> Option<(f64, i8)> {
    let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
    let p = [[t[0][b], t[0][c]], [t[1][b], t[1][c]], [t[2][b], t[2][c]]];
    let area = orient2(p[0], p[1], p[2]);
    if area == 0.0 || !area.is_finite() {
        return None;
    }
    let s = if area > 0.0 { 1.0 } else { -1.0 };
    let mut e = [0.0; 3];
    for k in 0..3 {
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        e[k] = edge_fn(p[i], p[j], q);
        let v = s * e[k];
        if v < 0.0 {
            return None;
        }
        if v == 0.0 {
            let d =
                if s > 0.0 { [p[j][0] - p[i][0], p[j][1] - p[i][1]] } else { [p[i][0] - p[j][0], p[i][1] - p[j][1]] };
            if !tie_included(d) {
                return None;
            }
        }
    }
    let sum = e[0] + e[1] + e[2];
    let h = if sum != 0.0 {
        (e[0] * t[0][axis] + e[1] * t[1][axis] + e[2] * t[2][axis]) / sum
    } else {
        (t[0][axis] + t[1][axis] + t[2][axis]) / 3.0
    };
    Some((h, if s > 0.0 { 1 } else { -1 }))
}

/// Inside/outside/unknown for every lattice point from rays along `axis`, indexed like [`Lattice::index`];
/// also the number of lines whose crossings do not sum to zero.
fn axis_verdicts(soup: &[[[f64; 3]; 3]], lat: &Lattice, axis: usize) -> (Vec<u8>, usize) {
    let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
    let (nb, nc, na) = (lat.n[b], lat.n[c], lat.n[axis]);
    // Bucket triangles by the lattice rows (b index) their projection spans.
    let mut rows: Vec<Vec<u32>> = vec![Vec::new(); nb];
    for (ti, t) in soup.iter().enumerate() {
        let lo = t[0][b].min(t[1][b]).min(t[2][b]);
        let hi = t[0][b].max(t[1][b]).max(t[2][b]);
        if let Some((r0, r1)) = lat.range(b, lo, hi) {
            for row in &mut rows[r0..=r1] {
                row.push(ti as u32);
            }
        }
    }
    let slabs: Vec<(Vec<u8>, usize)> = rows
        .par_iter()
        .enumerate()
        .map(|(ib, tris)| {
            let yb = lat.coord(b, ib);
            let mut lines: Vec<Vec<(f64, i8)>> = vec![Vec::new(); nc];
            for &ti in tris {
                let t = &soup[ti as usize];
                let lo = t[0][c].min(t[1][c]).min(t[2][c]);
                let hi = t[0][c].max(t[1][c]).max(t[2][c]);
                if let Some((c0, c1)) = lat.range(c, lo, hi) {
                    for ic in c0..=c1 {
                        if let Some(hit) = ray_hit(t, axis, [yb, lat.coord(c, ic)]) {
                            lines[ic].push(hit);
                        }
                    }
                }
            }
            let mut out = vec![0u8; nc * na];
            let mut open = 0;
            for (ic, line) in lines.iter_mut().enumerate() {
                let row = &mut out[ic * na..(ic + 1) * na];
                if line.iter().map(|h| i64::from(h.1)).sum::<i64>() != 0 {
                    row.fill(UNKNOWN);
                    open += 1;
                    continue;
                }
                line.sort_unstable_by(|x, y| x.0.total_cmp(&y.0));
                // w(s) = sum of signs of crossings beyond s = −(sum of signs at or before s).
                let (mut next, mut before) = (0usize, 0i64);
                for (ia, v) in row.iter_mut().enumerate() {
                    let s = lat.coord(axis, ia);
                    while next < line.len() && line[next].0 <= s {
                        before += i64::from(line[next].1);
                        next += 1;
                    }
                    *v = u8::from(-before >= 1);
                }
            }
            (out, open)
        })
        .collect();
    let mut verdict = vec![0u8; lat.n[0] * lat.n[1] * lat.n[2]];
    let mut open = 0;
    for (ib, (slab, o)) in slabs.iter().enumerate() {
        open += o;
        for ic in 0..nc {
            for ia in 0..na {
                let mut ijk = [0usize; 3];
                ijk[axis] = ia;
                ijk[b] = ib;
                ijk[c] = ic;
                verdict[lat.index(ijk)] = slab[ic * na + ia];
            }
        }
    }
    (verdict, open)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_dir::TmpDir;

    /// A fresh temporary directory for one test (removed when it ends).
    fn tmp_dir(name: &str) -> TmpDir {
        TmpDir::new(&format!("perfuse-mesh-{name}"))
    }

    /// Axis-aligned box [lo, hi], outward triangles.
    fn cube(lo: [f64; 3], hi: [f64; 3]) -> TriMesh {
        let v = |i: usize| {
            [
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            ]
        };
        let vertices = (0..8).map(v).collect();
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let triangles = quads.iter().flat_map(|q: &[u32; 4]| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
        TriMesh { vertices, triangles }
    }

    /// Icosphere of radius r about c, `level` subdivisions (20·4^level triangles), outward.
    fn icosphere(c: [f64; 3], r: f64, level: usize) -> TriMesh {
        let t = (1.0 + 5f64.sqrt()) / 2.0;
        let mut vertices: Vec<[f64; 3]> = vec![
            [-1.0, t, 0.0],
            [1.0, t, 0.0],
            [-1.0, -t, 0.0],
            [1.0, -t, 0.0],
            [0.0, -1.0, t],
            [0.0, 1.0, t],
            [0.0, -1.0, -t],
            [0.0, 1.0, -t],
            [t, 0.0, -1.0],
            [t, 0.0, 1.0],
            [-t, 0.0, -1.0],
            [-t, 0.0, 1.0],
        ];
        let mut tris: Vec<[u32; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for v in &mut vertices {
            let l = norm(*v);
            *v = v.map(|x| x / l);
        }
        for _ in 0..level {
            let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
            let mut next = Vec::new();
            for tr in &tris {
                let mut m = [0u32; 3];
                for e in 0..3 {
                    let (a, b) = (tr[e], tr[(e + 1) % 3]);
                    let key = (a.min(b), a.max(b));
                    m[e] = *mid.entry(key).or_insert_with(|| {
                        let p = [0, 1, 2].map(|i| vertices[a as usize][i] + vertices[b as usize][i]);
                        let l = norm(p);
                        vertices.push(p.map(|x| x / l));
                        (vertices.len() - 1) as u32
                    });
                }
                next.push([tr[0], m[0], m[2]]);
                next.push([tr[1], m[1], m[0]]);
                next.push([tr[2], m[2], m[1]]);
                next.push([m[0], m[1], m[2]]);
            }
            tris = next;
        }
        let vertices = vertices.iter().map(|v| [c[0] + r * v[0], c[1] + r * v[1], c[2] + r * v[2]]).collect();
        TriMesh { vertices, triangles: tris }
    }

    fn write_binary_stl(mesh: &TriMesh, path: &Path, header: &[u8; 80]) {
        let mut bytes = header.to_vec();
        bytes.extend_from_slice(&(mesh.triangles.len() as u32).to_le_bytes());
        for t in &mesh.triangles {
            bytes.extend_from_slice(&[0u8; 12]);
            for &i in t {
                for c in mesh.vertices[i as usize] {
                    bytes.extend_from_slice(&(c as f32).to_le_bytes());
                }
            }
            bytes.extend_from_slice(&[0u8; 2]);
        }
        std::fs::write(path, bytes).expect("write stl");
    }

    fn write_ascii_stl(mesh: &TriMesh, path: &Path, first_line: &str) {
        let mut s = format!("{first_line}\n");
        for t in &mesh.triangles {
            s.push_str("  facet normal 0 0 0\n    outer loop\n");
            for &i in t {
                let v = mesh.vertices[i as usize];
                s.push_str(&format!("      vertex {} {} {}\n", v[0], v[1], v[2]));
            }
            s.push_str("    endloop\n  endfacet\n");
        }
        s.push_str("endsolid cube\n");
        std::fs::write(path, s).expect("write ascii stl");
    }

    fn same_geometry(a: &TriMesh, b: &TriMesh) {
        assert_eq!(a.triangles.len(), b.triangles.len());
        assert_eq!(a.vertices.len(), b.vertices.len());
        assert!((a.volume() - b.volume()).abs() < 1e-6 * a.volume().abs(), "{} vs {}", a.volume(), b.volume());
        let (alo, ahi) = a.bounds();
        let (blo, bhi) = b.bounds();
        for k in 0..3 {
            assert!((alo[k] - blo[k]).abs() < 1e-6 && (ahi[k] - bhi[k]).abs() < 1e-6);
        }
    }

    #[test]
    fn cube_volume_winding_and_validation() {
        let m = cube([-0.5, -0.25, 0.0], [0.5, 0.25, 2.0]);
        assert!((m.volume() - 1.0).abs() < 1e-12);
        let r = m.validate(Path::new("cube")).expect("valid cube");
        assert!(r.closed);
        assert_eq!((r.edges, r.boundary_edges, r.components), (18, 0, 1));
        assert!((m.winding_number([0.1, 0.1, 1.0]) - 1.0).abs() < 1e-9);
        assert!(m.winding_number([2.0, 0.1, 1.0]).abs() < 1e-9);
        assert!(m.contains([0.0, 0.0, 0.5]));
        assert!(!m.contains([0.0, 0.0, -0.5]));
        // On a face: ½.
        assert!((m.winding_number([0.0, 0.0, 2.0]) - 0.5).abs() < 1e-9);
    }

    #[test]
    fn sphere_winding_numbers() {
        let s = icosphere([0.1, 0.2, 0.3], 1.0, 3);
        for p in [[0.1, 0.2, 0.3], [0.6, 0.2, 0.3], [0.1, -0.5, 0.5]] {
            assert!((s.winding_number(p) - 1.0).abs() < 1e-9, "{p:?}");
        }
        for p in [[2.0, 0.0, 0.0], [0.1, 0.2, -1.0], [1.0, 1.0, 1.0]] {
            assert!(s.winding_number(p).abs() < 1e-9, "{p:?}");
        }
    }

    #[test]
    fn sphere_sampling_matches_ball_volume() {
        let r = 1.0;
        let s = icosphere([0.0; 3], r, 4);
        let dx = 0.05;
        let (pts, stats) = sample_interior_stats(&s, dx, [0.013, 0.007, -0.011]).expect("sample");
        let expected = s.volume() / dx.powi(3);
        let rel = (pts.len() as f64 - expected).abs() / expected;
        assert!(rel < 0.02, "{} points vs {expected:.0} expected", pts.len());
        assert_eq!(stats.winding_fallbacks, 0, "closed mesh needs no winding-number fallback");
        let ball = 4.0 / 3.0 * std::f64::consts::PI * r * r * r / dx.powi(3);
        assert!((pts.len() as f64 - ball).abs() / ball < 0.03);
        // Ordered by (i, j, k), k fastest; every point inside.
        for w in pts.windows(2) {
            let a = (w[0][0], w[0][1], w[0][2]);
            let b = (w[1][0], w[1][1], w[1][2]);
            assert!(a < b);
        }
        for p in pts.iter().step_by(97) {
            assert!(s.contains(*p));
        }
    }

    #[test]
    fn cube_sampling_on_aligned_and_unaligned_lattices() {
        let m = cube([0.0; 3], [1.0, 0.5, 0.25]);
        let dx = 0.05;
        // Faces on lattice planes: every strictly interior point is in, nothing outside the closed box is,
        // and points on the faces are decided one way or the other.
        let pts = sample_interior(&m, dx, [0.0; 3]);
        let strictly = |p: &[f64; 3]| {
            p[0] > 1e-9 && p[0] < 1.0 - 1e-9 && p[1] > 1e-9 && p[1] < 0.5 - 1e-9 && p[2] > 1e-9 && p[2] < 0.25 - 1e-9
        };
        assert_eq!(pts.iter().filter(|p| strictly(p)).count(), 19 * 9 * 4);
        assert!(pts.len() <= 21 * 11 * 6);
        let unaligned = sample_interior(&m, dx, [0.021, 0.013, 0.007]);
        assert_eq!(unaligned.len(), 20 * 10 * 5);
    }

    #[test]
    fn octahedron_rays_through_vertices_and_edges() {
        // z-lines through (0, 0) hit both apexes exactly; lines through (i·Δx, j·Δx) with |i|+|j| = 4 run
        // along equator edges. The tie rules must keep every line's crossings consistent.
        let v = vec![
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        let triangles = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
        let m = TriMesh { vertices: v, triangles };
        assert!((m.volume() - 4.0 / 3.0).abs() < 1e-12);
        let dx = 0.25;
        let off = [0.0, 0.0, 0.1];
        let (pts, stats) = sample_interior_stats(&m, dx, off).expect("sample");
        assert_eq!(stats.open_lines, 0);
        let mut brute = Vec::new();
        for i in -4..=4 {
            for j in -4..=4 {
                for k in -5..=4 {
                    let p = [i as f64 * dx, j as f64 * dx, off[2] + k as f64 * dx];
                    if p[0].abs() + p[1].abs() + p[2].abs() < 1.0 {
                        brute.push(p);
                    }
                }
            }
        }
        assert_eq!(pts, brute);
    }

    #[test]
    fn sampling_agrees_with_brute_force_winding() {
        // Lattice through vertices and edges of a coarse sphere (offset 0): ray ties must be watertight.
        let s = icosphere([0.0; 3], 1.0, 2);
        let dx = 0.125;
        let pts = sample_interior(&s, dx, [0.0; 3]);
        let mut brute = Vec::new();
        for i in -8..=8 {
            for j in -8..=8 {
                for k in -8..=8 {
                    let p = [i as f64 * dx, j as f64 * dx, k as f64 * dx];
                    if s.contains(p) {
                        brute.push(p);
                    }
                }
            }
        }
        assert_eq!(pts, brute);
    }

    #[test]
    fn sphere_with_holes_is_sampled_correctly() {
        let r = 1.0;
        let mut s = icosphere([0.0; 3], r, 4);
        // Delete two triangles (one near each pole region) and keep the rest.
        s.triangles.remove(1000);
        s.triangles.remove(3);
        let rep = s.validate(Path::new("holed-sphere")).expect("small holes are tolerated");
        assert_eq!(rep.boundary_edges, 6);
        assert!(!rep.closed);
        let dx = 0.04;
        let off = [0.0; 3];
        let (pts, stats) = sample_interior_stats(&s, dx, off).expect("sample");
        assert!(stats.open_lines > 0, "some lattice lines pass through the holes: {stats:?}");
        let n = (r / dx).ceil() as i64 + 1;
        let mut analytic = 0usize;
        let mut agree = 0usize;
        let set: std::collections::HashSet<[u64; 3]> = pts.iter().map(|p| p.map(f64::to_bits)).collect();
        for i in -n..=n {
            for j in -n..=n {
                for k in -n..=n {
                    let p = [i as f64 * dx, j as f64 * dx, k as f64 * dx];
                    let inside_ball = dot(p, p) <= r * r;
                    analytic += usize::from(inside_ball);
                    let sampled = set.contains(&p.map(f64::to_bits));
                    agree += usize::from(inside_ball == sampled);
                }
            }
        }
        let total = ((2 * n + 1) as usize).pow(3);
        let disagree = total - agree;
        assert!((disagree as f64) < 0.01 * analytic as f64, "{disagree} disagreements of {analytic} inside");
    }

    #[test]
    fn lines_through_two_aligned_holes_fall_back_to_the_winding_number() {
        // Holes at both ends of the z axis: the z-line through them has no crossing at all (its signs sum
        // to zero, so it looks valid) and would call the whole column outside.
        let s = icosphere([0.0; 3], 1.0, 3);
        let tilt = (1.0 / ((1.0 + 5f64.sqrt()) / 2.0)).atan().to_degrees();
        let mut s = s.transformed(&Placement { rotate_deg: [tilt, 0.0, 0.0], ..Placement::default() });
        let top = (0..s.vertices.len()).max_by(|&a, &b| s.vertices[a][2].total_cmp(&s.vertices[b][2])).expect("v");
        let bottom = (0..s.vertices.len()).min_by(|&a, &b| s.vertices[a][2].total_cmp(&s.vertices[b][2])).expect("v");
        assert!(s.vertices[top][2] > 1.0 - 1e-9 && s.vertices[bottom][2] < -1.0 + 1e-9, "a vertex at each pole");
        let before = s.triangles.len();
        s.triangles.retain(|t| !t.contains(&(top as u32)) && !t.contains(&(bottom as u32)));
        assert_eq!(before - s.triangles.len(), 10);
        let dx = 0.05;
        let (pts, stats) = sample_interior_stats(&s, dx, [0.0; 3]).expect("sample");
        assert!(stats.winding_fallbacks > 0, "{stats:?}");
        let on_axis = pts.iter().filter(|p| p[0] == 0.0 && p[1] == 0.0).count();
        assert_eq!(on_axis, 39, "the column through both holes is inside from z = −0.95 to 0.95");
    }

    #[test]
    fn placement_fit_rotate_translate_mirror() {
        let m = cube([0.0; 3], [2.0, 1.0, 1.0]);
        let p = Placement {
            fit_size: Some(0.17),
            center: true,
            rotate_deg: [0.0, 0.0, 90.0],
            translate: [1.0, 2.0, 3.0],
            ..Placement::default()
        };
        p.check("scenario.ron").expect("valid placement");
        let t = m.transformed(&p);
        let (lo, hi) = t.bounds();
        // 2 m along x → 0.17 m, rotated 90° about z onto y, centred at the translation.
        assert!((hi[1] - lo[1] - 0.17).abs() < 1e-12);
        assert!((hi[0] - lo[0] - 0.085).abs() < 1e-12);
        for a in 0..3 {
            assert!((0.5 * (lo[a] + hi[a]) - p.translate[a]).abs() < 1e-12);
        }
        assert!((t.volume() - 0.17 * 0.085 * 0.085).abs() < 1e-12);
        let mirrored = m.transformed(&Placement { scale: -0.5, ..Placement::default() });
        assert!(mirrored.volume() > 0.0, "mirroring keeps normals outward");
        let bad = Placement { scale: 0.0, ..Placement::default() }.check("scenario.ron");
        assert!(matches!(bad, Err(MeshError::Placement { .. })));
        assert!(bad.map_err(|e| e.to_string()).expect_err("error").contains("scenario.ron"));
    }

    #[test]
    fn obj_and_stl_round_trips() {
        let dir = tmp_dir("roundtrip");
        let m = cube([-0.1, 0.0, 0.2], [0.3, 0.25, 0.5]);
        let obj = dir.join("cube.OBJ");
        m.write_obj(&obj, "test cube\nunits: metres").expect("write obj");
        let text = std::fs::read_to_string(&obj).expect("read back");
        assert!(text.starts_with("# test cube\n# units: metres\n"));
        let a = load_mesh(&obj).expect("load obj");
        same_geometry(&m, &a);
        let sorted = |m: &TriMesh| {
            let mut v = m.vertices.clone();
            v.sort_by(|a, b| a.partial_cmp(b).expect("finite"));
            v
        };
        assert_eq!(sorted(&a), sorted(&m), "OBJ round trip keeps coordinates exactly");

        let bin = dir.join("cube.stl");
        write_binary_stl(&m, &bin, &[b' '; 80]);
        let b = load_mesh(&bin).expect("load binary stl");
        same_geometry(&m, &b);
        b.validate(&bin).expect("welded binary STL is closed");

        // Binary STL whose header starts with "solid" (common exporter quirk).
        let mut header = [b' '; 80];
        header[..11].copy_from_slice(b"solid cube ");
        let bin2 = dir.join("cube_solid_header.stl");
        write_binary_stl(&m, &bin2, &header);
        same_geometry(&m, &load_mesh(&bin2).expect("binary with solid header"));

        let ascii = dir.join("cube_ascii.Stl");
        write_ascii_stl(&m, &ascii, "solid cube");
        let c = load_mesh(&ascii).expect("load ascii stl");
        same_geometry(&m, &c);
        c.validate(&ascii).expect("welded ascii STL is closed");
        let bare = dir.join("cube_bare.stl");
        write_ascii_stl(&m, &bare, "solid");
        same_geometry(&m, &load_mesh(&bare).expect("ascii stl with a bare `solid` line"));

        // stl_io's own writer, too.
        let tris: Vec<stl_io::Triangle> = m
            .triangles
            .iter()
            .map(|t| stl_io::Triangle {
                normal: stl_io::Normal::new([0.0; 3]),
                vertices: t.map(|i| stl_io::Vertex::new(m.vertices[i as usize].map(|x| x as f32))),
            })
            .collect();
        let mut f = std::fs::File::create(dir.join("w.stl")).expect("create");
        stl_io::write_stl(&mut f, tris.iter()).expect("stl_io write");
        drop(f);
        same_geometry(&m, &load_mesh(&dir.join("w.stl")).expect("load stl_io output"));
    }

    #[test]
    fn obj_objects_are_merged_and_quads_triangulated_and_inverted_flipped() {
        let dir = tmp_dir("merge");
        // A unit cube as two objects of quads, written inside out; shared vertices repeated per object.
        let text = "o bottom_and_sides\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
                    f 1 2 3 4\nf 1 5 6 2\nf 2 6 7 3\nf 3 7 8 4\nf 4 8 5 1\n\
                    o top\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nf 9 12 11 10\n";
        let path = dir.join("cube.obj");
        std::fs::write(&path, text).expect("write");
        let m = load_mesh(&path).expect("load");
        assert_eq!(m.triangles.len(), 12);
        assert_eq!(m.vertices.len(), 8, "duplicated vertices welded");
        assert!((m.volume() - 1.0).abs() < 1e-12, "inside-out file flipped: {}", m.volume());
        let r = m.validate(&path).expect("closed");
        assert!(r.closed);
    }

    fn err_text<T: std::fmt::Debug>(r: Result<T, MeshError>) -> (MeshError, String) {
        let e = r.expect_err("an error");
        let s = e.to_string();
        (e, s)
    }

    #[test]
    fn error_cases_name_the_file() {
        let dir = tmp_dir("errors");

        let missing = dir.join("missing.obj");
        let (e, s) = err_text(load_mesh(&missing));
        assert!(matches!(e, MeshError::Io { .. }), "{e:?}");
        assert!(s.contains("missing.obj"), "{s}");

        let garbage: Vec<u8> = (0..4000u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8 | 0x80).collect();
        for name in ["garbage.obj", "garbage.stl"] {
            let p = dir.join(name);
            std::fs::write(&p, &garbage).expect("write");
            let (e, s) = err_text(load_mesh(&p));
            assert!(matches!(e, MeshError::Parse { .. }), "{name}: {e:?}");
            assert!(s.contains(name), "{s}");
        }
        let short = dir.join("short.stl");
        std::fs::write(&short, b"abc").expect("write");
        assert!(matches!(load_mesh(&short), Err(MeshError::Parse { .. })));

        let empty = dir.join("empty.obj");
        std::fs::write(&empty, "# nothing here\nv 0 0 0\nv 1 0 0\n").expect("write");
        let (e, s) = err_text(load_mesh(&empty));
        assert!(matches!(e, MeshError::Empty { .. }), "{e:?}");
        assert!(s.contains("empty.obj"), "{s}");

        let nan = dir.join("nan.obj");
        std::fs::write(&nan, "v 0 0 0\nv 1 0 0\nv 0 NaN 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n")
            .expect("write");
        let (e, s) = err_text(load_mesh(&nan));
        assert!(matches!(e, MeshError::NonFinite { .. }), "{e:?}");
        assert!(s.contains("nan.obj"), "{s}");

        let big = dir.join("big.obj");
        icosphere([0.0; 3], 1.0, 2).write_obj(&big, "320 triangles").expect("write");
        let (e, s) = err_text(load_mesh_with_limit(&big, 100));
        assert!(matches!(e, MeshError::TooLarge { triangles: 320, limit: 100, .. }), "{e:?}");
        assert!(s.contains("big.obj"), "{s}");
        let big_stl = dir.join("big.stl");
        write_binary_stl(&icosphere([0.0; 3], 1.0, 2), &big_stl, &[0; 80]);
        assert!(matches!(load_mesh_with_limit(&big_stl, 100), Err(MeshError::TooLarge { triangles: 320, .. })));
        let big_ascii = dir.join("big_ascii.stl");
        write_ascii_stl(&icosphere([0.0; 3], 1.0, 2), &big_ascii, "solid s");
        assert!(matches!(load_mesh_with_limit(&big_ascii, 100), Err(MeshError::TooLarge { triangles: 320, .. })));
        assert!(matches!(icosphere([0.0; 3], 1.0, 2).validate_with_limit(&big, 100), Err(MeshError::TooLarge { .. })));

        let quad = dir.join("quad.obj");
        std::fs::write(&quad, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").expect("write");
        let m = load_mesh(&quad).expect("a quad parses");
        let (e, s) = err_text(m.validate(&quad));
        assert!(matches!(e, MeshError::Open { boundary_edges: 4, .. }), "{e:?}");
        assert!(s.contains("quad.obj"), "{s}");

        // Half of a finely tessellated sphere: few boundary edges (< 5 %) but an ambiguous winding number.
        let mut half = icosphere([0.0; 3], 1.0, 4);
        let verts = half.vertices.clone();
        half.triangles.retain(|t| t.iter().map(|&i| verts[i as usize][2]).sum::<f64>() > 0.0);
        let hp = dir.join("half_sphere.obj");
        half.write_obj(&hp, "hemisphere shell").expect("write");
        let hm = load_mesh(&hp).expect("parses");
        let (e, s) = err_text(hm.validate(&hp));
        match &e {
            MeshError::Open { boundary_edges, edges, .. } => {
                assert!((*boundary_edges as f64) < 0.05 * *edges as f64, "the winding rule, not the edge rule, fires")
            }
            other => panic!("expected Open, got {other:?}"),
        }
        assert!(s.contains("half_sphere.obj"), "{s}");

        // A sphere with a quarter cut away is open beyond repair too.
        let mut cut = icosphere([0.0; 3], 1.0, 4);
        let verts = cut.vertices.clone();
        cut.triangles.retain(|t| !t.iter().all(|&i| verts[i as usize][0] > 0.0 && verts[i as usize][1] > 0.0));
        assert!(matches!(cut.validate(Path::new("cut.stl")), Err(MeshError::Open { .. })));

        let ply = dir.join("liver.PLY");
        std::fs::write(&ply, "ply\n").expect("write");
        let (e, s) = err_text(load_mesh(&ply));
        assert!(matches!(&e, MeshError::UnsupportedFormat { extension, .. } if extension == ".ply"), "{e:?}");
        assert!(s.contains("liver.PLY"), "{s}");
        assert!(matches!(load_mesh(&dir.join("noext")), Err(MeshError::UnsupportedFormat { .. })));

        let mut inverted = cube([0.0; 3], [1.0; 3]);
        for t in &mut inverted.triangles {
            t.swap(1, 2);
        }
        assert!(matches!(inverted.validate(Path::new("inv")), Err(MeshError::Inverted { .. })));
        assert!(inverted.orient_outward());
        inverted.validate(Path::new("inv")).expect("flipped");

        let flat = TriMesh {
            vertices: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2], [0, 2, 1]],
        };
        let (e, _) = err_text(flat.validate(Path::new("flat.obj")));
        assert!(matches!(e, MeshError::Degenerate { .. }), "{e:?}");
        let bad_index = TriMesh { vertices: vec![[0.0; 3]], triangles: vec![[0, 1, 2]] };
        assert!(matches!(bad_index.validate(Path::new("x")), Err(MeshError::InvalidIndex { index: 1, .. })));
        assert!(matches!(TriMesh::default().validate(Path::new("x")), Err(MeshError::Empty { .. })));
        assert!(matches!(
            try_sample_interior(&cube([0.0; 3], [1.0; 3]), 0.0, [0.0; 3]),
            Err(MeshError::Lattice { .. })
        ));
        assert!(matches!(
            try_sample_interior(&cube([0.0; 3], [1.0; 3]), 1e-4, [0.0; 3]),
            Err(MeshError::Lattice { .. })
        ));
        assert!(sample_interior(&cube([0.0; 3], [1.0; 3]), f64::NAN, [0.0; 3]).is_empty());
    }

    #[test]
    fn overlapping_components_union() {
        // Two overlapping cubes in one mesh (common in artist meshes): the union is inside.
        let a = cube([0.0; 3], [1.0; 3]);
        let b = cube([0.5, 0.0, 0.0], [1.5, 1.0, 1.0]);
        let mut m = a.clone();
        let base = m.vertices.len() as u32;
        m.vertices.extend(&b.vertices);
        m.triangles.extend(b.triangles.iter().map(|t| t.map(|i| i + base)));
        let dx = 0.1;
        let pts = sample_interior(&m, dx, [0.05, 0.05, 0.05]);
        assert_eq!(pts.len(), 15 * 10 * 10);
    }
}
