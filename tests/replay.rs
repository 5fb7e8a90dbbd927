//! Recording and replay (issue 8): a scripted session — a scalpel driven along a cutting path with
//! commands at chosen steps, state hashes along the way — replays to identical hashes and the identical final
//! state on the same back-end (CPU, and GPU against itself); a recording cut mid-chunk replays up to
//! its last good chunk with a warning.

mod common;

use common::gpu::gpu_test;
use common::scenes::perfused_block;
use perfuse::replay::format::{ChunkKind, read_recording_file};
use perfuse::replay::session::{Player, RecordedSimulation, Recorder, replay};
use perfuse::sim::{BackendKind, Command, Simulation};

fn temp(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("perfuse-{}-{name}", std::process::id()))
}

/// The block scene with its tool replaced by a scalpel: a thin blade (0.6 mm × 5 mm × 1.2 mm) parked
/// above the tissue.
fn scalpel_block() -> perfuse::scenario::Scenario {
    let text = common::scenes::PERFUSED_BLOCK_3D.replace(
        r#"Boundary(name: "tool", shape: Sphere(centre: (0.003, 0.003, 0.005), radius: 0.0008),
                 motion: Translate(velocity: (0.0, 0.0, -0.1))),"#,
        r#"Boundary(name: "scalpel", shape: Box(min: (0.0017, 0.0005, 0.0046), max: (0.0023, 0.0055, 0.0058)),
                 spacing: Some(0.0003), tool: Some(Tool(kind: Scalpel, max_speed: 0.2))),"#,
    );
    assert_ne!(text, common::scenes::PERFUSED_BLOCK_3D, "the tool was replaced");
    perfuse::scenario::Scenario::from_str_named(&text, "scalpel_block.ron").expect("valid")
}

/// Records a scripted scalpel session: the blade lowered into the tissue, drawn through it (bonds
/// break), lifted out, with state hashes along the way; returns the final state hash and the bonds
/// broken.
fn record(backend: BackendKind, path: &std::path::Path) -> (u64, u64) {
    let sc = scalpel_block();
    let sim = Simulation::new(&sc, backend).expect("sim");
    let recorder = Recorder::create(path, &sc, &format!("{backend:?}"), "").expect("recorder");
    let mut rs = RecordedSimulation { sim, recorder: Some(recorder) };
    rs.relax().expect("relax");
    // centre positions of the blade: above the tissue, 1 mm deep, drawn 2.2 mm along x, lifted out
    let path_points =
        [[0.002, 0.003, 0.0052], [0.002, 0.003, 0.0036], [0.0042, 0.003, 0.0036], [0.0042, 0.003, 0.0052]];
    let speed = 1.0;
    rs.apply(&Command::PlaceObject { object: 1, position: path_points[0] }).expect("place");
    for w in path_points.windows(2) {
        rs.apply(&Command::MoveObject { object: 1, target: w[1], speed }).expect("move");
        let dist = (0..3).map(|a| (w[1][a] - w[0][a]).powi(2)).sum::<f64>().sqrt();
        let t_end = rs.sim.time() + dist / speed + 1e-4;
        rs.sim.advance_until(t_end, u64::MAX, |_| {}).expect("advance");
        rs.checkpoint().expect("hash");
    }
    rs.apply(&Command::SetGravity([0.0, 0.0, -4.0])).expect("gravity");
    rs.sim.advance(20, f64::INFINITY).expect("advance");
    rs.checkpoint().expect("hash");
    let st = rs.sim.read_state().expect("state");
    rs.recorder.take().expect("recording").finish().expect("finish");
    (st.hash(), st.broken_bonds())
}

/// A lower bound of the header's size: it holds the scenario text plus a few short fields.
fn rec_header_len(path: &std::path::Path) -> usize {
    read_recording_file(path).expect("readable").header.scenario_text.len() + 16
}

fn record_and_replay(backend: BackendKind, name: &str) {
    let path = temp(name);
    let (live, broken) = record(backend, &path);
    let rec = read_recording_file(&path).expect("readable");
    assert!(rec.complete && rec.warnings.is_empty(), "{:?}", rec.warnings);
    let out = replay(&rec, backend, true).expect("replay");
    eprintln!(
        "{backend:?}: {} commands, {} hashes checked, {} steps, {broken} bonds cut, {} bytes",
        out.commands,
        out.hashes_checked,
        out.steps,
        std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0)
    );
    assert!(broken > 0, "the scalpel cut no bond");
    assert!(out.commands >= 5 && out.hashes_checked >= 4);
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

/// The block scene with a short damped relaxation (the clock runs from −2 ms to 0 before the session).
fn relaxed_block() -> perfuse::scenario::Scenario {
    let text = common::scenes::PERFUSED_BLOCK_3D.replace(
        "duration: 0.01,",
        "duration: 0.01,\n    relaxation: Some(Relaxation(duration: 0.002, damping: 50.0)),",
    );
    perfuse::scenario::Scenario::from_str_named(&text, "relaxed_block.ron").expect("valid")
}

/// A scripted session with keyframes: relaxation (keyframe at its end), a tool path with a keyframe
/// and state hash after each leg. Returns the recording's path and the steps of its keyframes.
fn record_with_keyframes(backend: BackendKind, name: &str) -> (std::path::PathBuf, Vec<u64>) {
    let sc = relaxed_block();
    let path = temp(name);
    let sim = Simulation::new(&sc, backend).expect("sim");
    let recorder = Recorder::create(&path, &sc, &format!("{backend:?}"), "").expect("recorder");
    let mut rs = RecordedSimulation { sim, recorder: Some(recorder) };
    rs.relax().expect("relax");
    rs.keyframe(None).expect("keyframe");
    let mut keyframes = vec![rs.sim.stats().steps];
    rs.apply(&Command::PlaceObject { object: 1, position: [0.0025, 0.003, 0.0052] }).expect("place");
    for (k, p) in [[0.0035, 0.003, 0.0046], [0.0045, 0.0032, 0.0046]].iter().enumerate() {
        rs.apply(&Command::MoveObject { object: 1, target: *p, speed: 0.05 }).expect("move");
        rs.sim.advance(20 + 3 * k as u32, f64::INFINITY).expect("advance");
        rs.checkpoint().expect("hash");
        rs.sim.advance(7, f64::INFINITY).expect("advance");
        rs.keyframe(None).expect("keyframe");
        keyframes.push(rs.sim.stats().steps);
    }
    rs.apply(&Command::SetGravity([0.0, 0.0, -4.0])).expect("gravity");
    rs.sim.advance(15, f64::INFINITY).expect("advance");
    rs.checkpoint().expect("hash");
    rs.recorder.take().expect("recording").finish().expect("finish");
    (path, keyframes)
}

fn hash_of(p: &mut Player) -> u64 {
    p.simulation_mut().read_state().expect("state").hash()
}

/// Seeking (back to a keyframe, forward past one, by time, and back before every keyframe) and then
/// stepping gives bit for bit the state a straight replay reaches; a take-over branch names its
/// parent, starts from a keyframe and replays to the live branch's final state.
fn seek_and_take_over(backend: BackendKind, name: &str) {
    let (path, keyframes) = record_with_keyframes(backend, name);
    let rec = read_recording_file(&path).expect("readable");
    assert!(rec.is_clean(), "relaxation commands must not break the time order: {:?}", rec.warnings);
    assert_eq!(rec.chunks_of(ChunkKind::Keyframe).count(), 3);
    // The relaxation's chunks sit at t = 0 on the timeline; stamps never decrease.
    assert!(rec.chunks.windows(2).all(|w| w[0].t_s <= w[1].t_s && w[0].step <= w[1].step));
    let bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    let end = rec.chunks.last().map(|c| c.step).expect("chunks");
    let targets = [keyframes[1] + 5, keyframes[0] + 2, end];

    // Straight replays to each target (a fresh player each time).
    let straight: Vec<u64> = targets
        .iter()
        .map(|&s| {
            let mut p = Player::new(rec.clone(), backend, true).expect("player");
            p.play_to_step(s).expect("play");
            assert_eq!(p.steps(), s);
            hash_of(&mut p)
        })
        .collect();

    // One player seeking around: to the end, back, back further, forward again.
    let mut p = Player::new(rec.clone(), backend, true).expect("player");
    p.play_to_end().expect("play");
    assert!(p.at_end());
    assert_eq!(hash_of(&mut p), straight[2]);
    p.seek_step(targets[0]).expect("seek back");
    assert_eq!(hash_of(&mut p), straight[0], "seek back to step {} then step ≠ straight run", targets[0]);
    p.seek_step(targets[1]).expect("seek back further");
    assert_eq!(hash_of(&mut p), straight[1], "seek to step {} ≠ straight run", targets[1]);
    p.seek_step(targets[2]).expect("seek forward");
    assert_eq!(hash_of(&mut p), straight[2]);
    p.seek_step(1).expect("seek before every keyframe");
    let mut fresh = Player::new(rec.clone(), backend, true).expect("player");
    fresh.play_to_step(1).expect("play");
    assert_eq!(hash_of(&mut p), hash_of(&mut fresh), "seek to the start ≠ straight run");
    assert!(p.outcome().keyframes_restored >= 3, "{:?}", p.outcome());
    assert!(p.outcome().mismatches.is_empty(), "{:?}", p.outcome().mismatches);

    // By time: the state of the first step boundary at or past t (with every chunk stamped ≤ t).
    let t_target = rec.chunks.iter().find(|c| c.step >= targets[0]).map(|c| c.t_s).expect("chunk");
    p.seek_time(t_target).expect("seek time");
    let at = p.steps();
    let mut fresh = Player::new(rec.clone(), backend, true).expect("player");
    fresh.play_to_time(t_target).expect("play");
    assert_eq!(fresh.steps(), at);
    assert_eq!(hash_of(&mut p), hash_of(&mut fresh));

    // Take over at targets[0] with a branch recording; drive the tool elsewhere.
    p.seek_step(targets[0]).expect("seek");
    let branch_path = temp(&format!("{name}-branch"));
    let (mut live, _) = p.take_over(Some((&branch_path, &format!("{backend:?}"), ""))).expect("take over");
    live.apply(&Command::MoveObject { object: 1, target: [0.003, 0.0045, 0.0047], speed: 0.05 }).expect("move");
    live.sim.advance(12, f64::INFINITY).expect("advance");
    live.checkpoint().expect("hash");
    live.sim.advance(6, f64::INFINITY).expect("advance");
    live.checkpoint().expect("hash");
    let live_hash = live.sim.read_state().expect("state").hash();
    live.recorder.take().expect("branch").finish().expect("finish");
    let branch = read_recording_file(&branch_path).expect("branch readable");
    let parent = branch.header.parent.as_ref().expect("branch names its parent");
    assert_eq!(parent.step, targets[0]);
    assert_eq!(parent.hash_of_parent_header, rec.header.header_hash());
    assert_eq!(branch.header.scenario_hash, rec.header.scenario_hash);
    assert_eq!(branch.chunks.first().map(|c| c.kind), Some(ChunkKind::Keyframe));
    let out = replay(&branch, backend, true).expect("branch replays");
    assert!(out.hashes_checked >= 3 && out.mismatches.is_empty(), "{out:?}");
    assert_eq!(out.final_hash, live_hash, "branch replay ≠ the live branch");
    eprintln!(
        "{backend:?}: {bytes} bytes with 3 keyframes, {} steps; branch {} bytes",
        end,
        std::fs::metadata(&branch_path).map(|m| m.len()).unwrap_or(0)
    );

    // A branch whose first keyframe is damaged fails with a clear error naming the parent.
    let mut damaged = branch.clone();
    if let Some(c) = damaged.chunks.first_mut() {
        c.payload.truncate(c.payload.len() / 2);
    }
    let err = replay(&damaged, backend, false).expect_err("damaged branch start");
    assert!(err.to_string().contains("branch") && err.to_string().contains(&parent.file), "{err}");
    let _ = std::fs::remove_file(&path);
    let _ = std::fs::remove_file(&branch_path);
}

#[test]
fn seek_and_take_over_are_bit_identical_on_the_cpu() {
    seek_and_take_over(BackendKind::Cpu, "seek-cpu.pfr");
}

#[test]
fn seek_and_take_over_are_bit_identical_on_the_gpu() {
    gpu_test("seek_and_take_over_are_bit_identical_on_the_gpu", |_ctx| {
        seek_and_take_over(BackendKind::Gpu, "seek-gpu.pfr");
    });
}

/// A keyframe restores only into a simulation of the same back-end kind and scenario: otherwise a
/// clear error, and the simulation is left as it was.
#[test]
fn a_keyframe_that_does_not_fit_is_refused() {
    let sc = perfused_block();
    let mut a = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    a.advance(3, f64::INFINITY).expect("advance");
    let snap = a.snapshot().expect("snapshot");
    let bytes = snap.encode();
    assert!(perfuse::sim::snapshot::Snapshot::decode(&bytes[..bytes.len() / 2]).is_err());
    let mut other = Simulation::new(&relaxed_block_other_size(), BackendKind::Cpu).expect("sim");
    let before = other.read_state().expect("state").hash();
    let err = other.restore(snap.clone()).expect_err("another scenario");
    assert!(err.to_string().contains("does not fit"), "{err}");
    assert_eq!(other.read_state().expect("state").hash(), before);
    let mut fresh = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    fresh.restore(snap).expect("same scenario");
    assert_eq!(fresh.read_state().expect("state").hash(), a.read_state().expect("state").hash());
}

fn relaxed_block_other_size() -> perfuse::scenario::Scenario {
    let text = common::scenes::PERFUSED_BLOCK_3D.replace("max: (0.005, 0.005, 0.004)", "max: (0.005, 0.005, 0.0035)");
    perfuse::scenario::Scenario::from_str_named(&text, "smaller_block.ron").expect("valid")
}

/// `perfuse bench --record` (issue 8 §1: "measure it"): a run recorded as the viewer records it is
/// compared with one that is not; the keyframe's cost and size are reported and the file is removed.
#[test]
fn bench_measures_the_cost_of_recording() {
    let dir = temp("bench-record");
    std::fs::create_dir_all(&dir).expect("dir");
    let scenario = dir.join("block.ron");
    std::fs::write(&scenario, common::scenes::PERFUSED_BLOCK_3D).expect("write");
    let file = dir.join("bench.pfrec");
    let (plain, rec) =
        perfuse::bench::record_overhead(&perfused_block(), BackendKind::Cpu, 0.3, &file, Default::default())
            .expect("measured");
    let c = rec.recording.as_ref().expect("recording cost");
    assert!(plain.recording.is_none());
    assert!(c.keyframes >= 1 && c.keyframe_bytes > 1000.0 && c.file_bytes as f64 >= c.keyframe_bytes, "{c:?}");
    assert!(c.overhead_policy_pct.is_finite() && c.overhead_measured_pct.is_finite() && c.bytes_per_simulated_s > 0.0);
    assert!(!file.exists(), "the temporary recording is removed");
    // The CLI prints both tables.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_perfuse"))
        .arg("bench")
        .arg("--scenario")
        .arg(&scenario)
        .args(["--backends", "cpu", "--seconds", "0.3", "--record"])
        .output()
        .expect("runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("keyframe MB") && stdout.contains("overhead %"), "{stdout}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The block scene with everything a keyframe can hold: a membrane, an inlet and a sink, a held
/// suction, besides the tissue's bonds, the blood, the floor and the moving tool.
fn keyframe_block() -> perfuse::scenario::Scenario {
    let text = common::scenes::PERFUSED_BLOCK_3D.replace(
        "    duration: 0.01,",
        r#"    membrane: Some(Membrane(threshold: 0.5, count: 3, radius: 0.5, angle: 0.7853981633974483)),
    emitters: [ Emitter(name: "inlet", region: Box(min: (0.0005, 0.0005, 0.0045), max: (0.0015, 0.0015, 0.0055)),
        direction: (0.0, 0.0, -1.0), flow: Constant(1e-9)) ],
    sinks: [ Sink(name: "drain", region: Box(min: (0.0, 0.0, 0.0015), max: (0.0005, 0.006, 0.002))) ],
    duration: 0.01,"#,
    );
    assert_ne!(text, common::scenes::PERFUSED_BLOCK_3D, "the features were added");
    perfuse::scenario::Scenario::from_str_named(&text, "keyframe_block.ron").expect("valid")
}

/// Keyframes (and the replay files that carry them) are postcard, which writes no field names: a
/// field added to the state decodes an old keyframe into garbage unless `SNAPSHOT_LAYOUT` moves, so
/// that the old file is refused by number. The shape of a keyframe (its types, field names and
/// variants, not its values; the GPU's buffers by their sizes) is pinned here to the layout number on
/// both back-ends: a change of `CpuState`, `GpuSnapshot` or the records of a state buffer fails this
/// test until the layout is bumped and the new fingerprints are written below. (A change of the test
/// scene's particle counts moves the GPU fingerprint alone; then only the fingerprint is rewritten.)
#[test]
fn keyframe_shape_is_pinned_to_the_snapshot_layout() {
    use common::shape::{fnv1a, shape_of};
    use perfuse::sim::snapshot::SNAPSHOT_LAYOUT;
    let shape = |backend: BackendKind| {
        let mut sim = Simulation::new(&keyframe_block(), backend).expect("sim");
        sim.apply(&Command::SetSuction(false)).expect("hold the suction");
        sim.advance(3, f64::INFINITY).expect("advance");
        let snap = sim.snapshot().expect("snapshot");
        shape_of(&snap)
    };
    let cpu = shape(BackendKind::Cpu);
    eprintln!("CPU keyframe shape ({} chars): {cpu}", cpu.len());
    let bump = "the keyframe's encoding changed: bump SNAPSHOT_LAYOUT (src/sim/snapshot.rs, with a line on what \
                changed) and write the new layout and fingerprint here";
    assert_eq!((SNAPSHOT_LAYOUT, fnv1a(&cpu)), (6, 12_865_145_542_586_391_845), "{bump}");
    gpu_test("keyframe_shape_is_pinned_to_the_snapshot_layout", |_ctx| {
        let gpu = shape(BackendKind::Gpu);
        eprintln!("GPU keyframe shape ({} chars): {gpu}", gpu.len());
        assert_eq!((SNAPSHOT_LAYOUT, fnv1a(&gpu)), (6, 4_736_115_783_571_168_898), "{bump}");
    });
}

/// The viewer's cache of relaxed states (`replay::relaxed_cache`): a simulation that restores the
/// cached state is where the relaxation left the one that kept it, bit for bit, and steps on to the
/// same states; another scenario finds nothing; a damaged file is reported, naming it, and leaves
/// the simulation as built; only the newest `KEEP` files stay.
#[test]
fn a_cached_relaxed_state_restores_the_relaxation_bit_for_bit() {
    use perfuse::replay::relaxed_cache::{CacheError, Engine, KEEP, RelaxedCache};
    let dir = temp("relaxed-cache");
    let _ = std::fs::remove_dir_all(&dir);
    let cache = RelaxedCache::new(&dir);
    let sc = perfused_block()
        .with_override("relaxation=Some(Relaxation(duration: 4e-5, damping: 20.0, gravity_solid_only: true))")
        .expect("valid");
    // the first launch relaxes and keeps the state at t = 0
    let mut a = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    assert!(cache.restore(&sc, &mut a).expect("no file is not an error").is_none());
    a.relax(|_| {}).expect("relax");
    let relaxed_steps = a.stats().steps;
    assert!(relaxed_steps >= 2 && a.time().abs() < 1e-12, "{relaxed_steps} steps, t = {}", a.time());
    let snap = a.snapshot().expect("snapshot");
    let file = cache.store(&sc, &Engine::of(&a), &snap, None).expect("stored");
    assert_eq!(file, cache.path_for(&sc, &Engine::of(&a)));
    let hash0 = a.read_state().expect("state").hash();
    a.advance(5, f64::INFINITY).expect("step");
    let hash5 = a.read_state().expect("state").hash();
    // the next launch starts there without relaxing
    let mut b = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    let restored = cache.restore(&sc, &mut b).expect("readable").expect("cached");
    assert_eq!(restored.file, file);
    assert_eq!(b.stats().steps, relaxed_steps);
    assert_eq!(b.read_state().expect("state").hash(), hash0, "the relaxed state, bit for bit");
    b.advance(5, f64::INFINITY).expect("step");
    assert_eq!(b.read_state().expect("state").hash(), hash5, "and the same states after it");
    // another scenario (a changed parameter) has no cached state
    let other = sc.with_override("liquid.viscosity=0.4").expect("valid");
    let mut c = Simulation::new(&other, BackendKind::Cpu).expect("sim");
    assert!(cache.restore(&other, &mut c).expect("readable").is_none());
    // a damaged file: reported with its name, the simulation left as built
    let mut bytes = std::fs::read(&file).expect("read");
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x5a;
    std::fs::write(&file, &bytes).expect("write");
    let mut d = Simulation::new(&sc, BackendKind::Cpu).expect("sim");
    let err = cache.restore(&sc, &mut d).expect_err("damaged");
    let msg = err.to_string();
    assert!(matches!(err, CacheError::Replay(_) | CacheError::Unusable { .. }), "{err:?}");
    assert!(msg.contains(&file.display().to_string()), "names the file: {msg}");
    assert_eq!((d.stats().steps, d.time()), (0, Simulation::new(&sc, BackendKind::Cpu).expect("sim").time()));
    // storing again replaces it; other scenarios' files beyond KEEP are pruned, oldest first
    cache.store(&sc, &Engine::of(&a), &snap, None).expect("stored again");
    assert!(cache.restore(&sc, &mut d).expect("readable").is_some());
    for k in 0..KEEP + 2 {
        let s = sc.with_override(&format!("liquid.viscosity={}", 0.5 + k as f64 * 0.01)).expect("valid");
        std::thread::sleep(std::time::Duration::from_millis(20));
        cache.store(&s, &Engine::of(&a), &snap, None).expect("stored");
    }
    let kept = std::fs::read_dir(&dir).expect("dir").filter_map(Result::ok).count();
    assert_eq!(kept, KEEP, "only the newest {KEEP} are kept");
    assert!(!file.exists(), "the oldest went first");
    // a writer that died before its rename leaves NAME.tmpPID: removed once it is an hour old
    let (stale, fresh) = (dir.join("dead.tmp12345"), dir.join("busy.tmp678"));
    for f in [&stale, &fresh] {
        std::fs::write(f, b"partial").expect("write");
    }
    let two_hours_ago = std::time::SystemTime::now() - std::time::Duration::from_secs(7200);
    std::fs::File::options().write(true).open(&stale).expect("open").set_modified(two_hours_ago).expect("mtime");
    cache.store(&sc, &Engine::of(&a), &snap, None).expect("stored");
    assert!(!stale.exists() && fresh.exists(), "stale temporary removed, a fresh one left alone");
    eprintln!("relaxed cache: {relaxed_steps} relaxation steps skipped, {} bytes per state", bytes.len());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The relaxed-state cache's key holds the bytes of a scenario's meshes, not only their path: an
/// edited `PerfusedMesh` file is another organ, whose state must not be restored.
#[test]
fn an_edited_mesh_is_another_relaxed_state() {
    use perfuse::replay::relaxed_cache::{Engine, RelaxedCache};
    let dir = temp("relaxed-mesh");
    std::fs::create_dir_all(&dir).expect("dir");
    let cube = |b: f64| {
        let v: Vec<String> = (0..8)
            .map(|k| format!("v {} {} {}", [0.0, b][k & 1], [0.0, b][(k >> 1) & 1], [0.0, b][(k >> 2) & 1]))
            .collect();
        let faces = "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
        std::fs::write(dir.join("cube.obj"), format!("{}\n{faces}", v.join("\n"))).expect("write mesh");
    };
    let text = r#"Scenario(
    name: "mesh_key", dimensions: 3,
    domain: Domain(min: (-0.01, -0.01, -0.01), max: (0.07, 0.07, 0.07)),
    liquid: Some(Liquid(density: 1000.0, viscosity: 0.001, sound_speed: Some(10.0))),
    solid: Some(Solid(density: 1000.0, c10: 900.0, c01: 100.0, k_s: 2.0e4, n_sat: 0.7, k_sat: 2.0e4, friction: 1.0e6)),
    numerics: Numerics(dx_solid: Some(0.005), dx_liquid: Some(0.005), h_over_dx: 1.3, sound_speed_solid: Some(10.0)),
    particles: [PerfusedMesh(file: "cube.obj", solid_fraction: 0.7, liquid_fraction: 0.3)],
    duration: 0.1,
)"#;
    cube(0.05);
    let sc = perfuse::scenario::Scenario::from_str_named(text, &dir.join("mesh_key.ron").to_string_lossy())
        .unwrap_or_else(|e| panic!("{e}"));
    let cache = RelaxedCache::new(dir.join("cache"));
    let engine = Engine { backend: "cpu".into(), adapter: String::new() };
    let before = cache.path_for(&sc, &engine);
    assert_eq!(before, cache.path_for(&sc, &engine), "the key is stable");
    cube(0.055);
    assert_ne!(before, cache.path_for(&sc, &engine), "an edited mesh keys another state");
    let _ = std::fs::remove_dir_all(&dir);
}
