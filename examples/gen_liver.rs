//! Writes `assets/meshes/liver.obj`, the procedural liver (see `src/liver.rs`), and prints its figures and the
//! particle counts / sampling times at Δx = 5, 4, 3 mm.
//!
//! ```text
//! cargo run --release --example gen_liver            # writes assets/meshes/liver.obj
//! cargo run --release --example gen_liver -- OUT.obj  # writes elsewhere
//! ```

use perfuse::scenario::liver::{ASSET_CELLS, liver_mesh, obj_header};
use perfuse::scenario::mesh::sample_interior_stats;
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets").join("meshes").join("liver.obj"));
    let t0 = Instant::now();
    let (mesh, landmarks) = liver_mesh(ASSET_CELLS);
    let generated = t0.elapsed();
    let report = mesh.validate(&out)?;
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir)?;
    }
    mesh.write_obj(&out, &obj_header(&mesh, &landmarks, ASSET_CELLS))?;
    let (lo, hi) = mesh.bounds();
    println!("wrote {} in {:.0} ms", out.display(), generated.as_secs_f64() * 1e3);
    println!(
        "{} vertices, {} triangles, {} edges, {} boundary, {} component(s), closed {}",
        report.vertices, report.triangles, report.edges, report.boundary_edges, report.components, report.closed
    );
    println!(
        "extent {:.1} × {:.1} × {:.1} cm (x left-right, y up, z antero-posterior), volume {:.0} cm³, area {:.0} cm²",
        (hi[0] - lo[0]) * 100.0,
        (hi[1] - lo[1]) * 100.0,
        (hi[2] - lo[2]) * 100.0,
        report.volume * 1e6,
        report.area * 1e4
    );
    println!("ligament_center {:?} radius {}", landmarks.ligament_center, landmarks.ligament_radius);
    println!("rayon threads: {}", rayon::current_num_threads());
    for dx in [0.005, 0.004, 0.003, 0.002] {
        let t = Instant::now();
        let (points, stats) = sample_interior_stats(&mesh, dx, [0.5 * dx; 3])?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        println!(
            "dx = {:.0} mm: {} particles of {} lattice points ({} by winding number) in {:.1} ms; \
             particles × dx³ = {:.0} cm³",
            dx * 1e3,
            points.len(),
            stats.candidates,
            stats.winding_fallbacks,
            ms,
            points.len() as f64 * dx.powi(3) * 1e6
        );
    }
    Ok(())
}
