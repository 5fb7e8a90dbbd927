//! Recording and replay (issue 8): a scripted session — a tool driven along a path with commands at
//! chosen steps, state hashes along the way — replays to identical hashes and the identical final
//! state on the same back-end (CPU, and GPU against itself); a recording cut mid-chunk replays up to
//! its last good chunk with a warning.

mod common;

use common::gpu::gpu_test;
use common::scenes::perfused_block;
use perfuse::replay::format::read_recording_file;
use perfuse::replay::session::{RecordedSimulation, Recorder, replay};
use perfuse::sim::{BackendKind, Command, Simulation};

fn temp(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("perfuse-{}-{name}", std::process::id()))
}

/// Records a scalpel-like path of the block scene's tool; returns the final state hash.
fn record(backend: BackendKind, path: &std::path::Path) -> u64 {
    let sc = perfused_block();
    let sim = Simulation::new(&sc, backend).expect("sim");
    let recorder = Recorder::create(path, &sc, &format!("{backend:?}"), "").expect("recorder");
    let mut rs = RecordedSimulation { sim, recorder: Some(recorder) };
    rs.relax().expect("relax");
    let path_points = [[0.0025, 0.003, 0.0052], [0.0035, 0.003, 0.0046], [0.0045, 0.0032, 0.0046]];
    rs.apply(&Command::PlaceObject { object: 1, position: path_points[0] }).expect("place");
    for (k, p) in path_points.iter().enumerate().skip(1) {
        rs.sim.advance(17 + 5 * k as u32, f64::INFINITY).expect("advance");
        rs.checkpoint().expect("hash");
        rs.apply(&Command::MoveObject { object: 1, target: *p, speed: 0.05 }).expect("move");
    }
    rs.apply(&Command::SetGravity([0.0, 0.0, -4.0])).expect("gravity");
    rs.sim.advance(30, f64::INFINITY).expect("advance");
    rs.checkpoint().expect("hash");
    let h = rs.sim.read_state().expect("state").hash();
    rs.recorder.take().expect("recording").finish().expect("finish");
    h
}

/// A lower bound of the header's size: it holds the scenario text plus a few short fields.
fn rec_header_len(path: &std::path::Path) -> usize {
    read_recording_file(path).expect("readable").header.scenario_text.len() + 16
}

fn record_and_replay(backend: BackendKind, name: &str) {
    let path = temp(name);
    let live = record(backend, &path);
    let rec = read_recording_file(&path).expect("readable");
    assert!(rec.complete && rec.warnings.is_empty(), "{:?}", rec.warnings);
    let out = replay(&rec, backend, true).expect("replay");
    eprintln!(
        "{backend:?}: {} commands, {} hashes checked, {} steps, {} bytes",
        out.commands,
        out.hashes_checked,
        out.steps,
        std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0)
    );
    assert!(out.commands >= 4 && out.hashes_checked >= 3);
    assert!(out.mismatches.is_empty(), "hash mismatches {:?}", out.mismatches);
    assert_eq!(out.final_hash, live, "replayed final state differs from the live one");

    // Cut mid-chunk: replays up to the last good chunk with a warning, no panic.
    let bytes = std::fs::read(&path).expect("bytes");
    let cut = temp(&format!("{name}-cut"));
    // Halfway through the chunks (past the header, which holds the scenario text).
    let header_end = 16 + rec_header_len(&path);
    let at = header_end + (bytes.len() - header_end) / 2 + 3;
    std::fs::write(&cut, &bytes[..at]).expect("write");
    let rec = read_recording_file(&cut).expect("header intact");
    assert!(!rec.complete && !rec.warnings.is_empty());
    let partial = replay(&rec, backend, true).expect("partial replay");
    assert!(partial.mismatches.is_empty());
    assert!(partial.steps <= out.steps);
    let _ = std::fs::remove_file(&path);
    let _ = std::fs::remove_file(&cut);
}

#[test]
fn scripted_session_replays_bit_identically_on_the_cpu() {
    record_and_replay(BackendKind::Cpu, "cpu.pfr");
}

#[test]
fn scripted_session_replays_bit_identically_on_the_gpu() {
    gpu_test("scripted_session_replays_bit_identically_on_the_gpu", |_ctx| {
        record_and_replay(BackendKind::Gpu, "gpu.pfr");
    });
}
