//! The viewer's simulation thread without a window (issue 5 §1): it publishes render buffer sets,
//! obeys pause/step/commands from the channel, and when the simulation diverges it pauses with the
//! last good state and reports it — the render side keeps its last published set to draw.

mod common;

use common::gpu::gpu_test;
use perfuse::app::sim_thread::{Control, Shared, SimStatus, lock, spawn};
use perfuse::scenario::Scenario;
use perfuse::sim::Command;
use std::sync::Arc;
use std::time::{Duration, Instant};

fn wait_for(shared: &Shared, what: &str, mut pred: impl FnMut(&SimStatus) -> bool) -> SimStatus {
    let start = Instant::now();
    loop {
        let st = lock(&shared.status).clone();
        if pred(&st) {
            return st;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "timed out waiting for {what}: {st:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn simulation_thread_publishes_obeys_and_pauses_on_divergence() {
    gpu_test("simulation_thread_publishes_obeys_and_pauses_on_divergence", |ctx| {
        let base = common::scenes::perfused_block();
        // A runaway-speed limit gravity soon exceeds: the run diverges after some steps.
        let sc = Scenario::from_str_with_overrides(
            &ron::ser::to_string(&base).expect("ron"),
            "block",
            &["numerics.max_speed=0.02".into()],
        )
        .expect("valid");
        let (tx, rx) = std::sync::mpsc::channel();
        let shared = Arc::new(Shared::default());
        let handle = spawn(ctx, false, sc, true, None, rx, shared.clone()).expect("thread");
        // Paused at start: a first set is published, no steps taken.
        let st = wait_for(&shared, "first publish", |s| s.publishes >= 1);
        assert!(st.paused && st.steps == 0, "{st:?}");
        assert!(lock(&shared.published).frames.is_some());
        // Single step while paused.
        tx.send(Control::Step).expect("send");
        wait_for(&shared, "one step", |s| s.steps == 1);
        // A command changes the published object poses.
        tx.send(Control::Sim(Command::PlaceObject { object: 1, position: [0.0035, 0.003, 0.0055] })).expect("send");
        let start = Instant::now();
        loop {
            let c = lock(&shared.published).info.objects[1].centre;
            if (c[0] - 0.0035).abs() < 1e-6 {
                break;
            }
            assert!(start.elapsed() < Duration::from_secs(30), "command not applied: {c:?}");
            std::thread::sleep(Duration::from_millis(20));
        }
        // Run: it diverges, pauses itself and reports; published sets stay.
        tx.send(Control::Pause(false)).expect("send");
        let st = wait_for(&shared, "divergence", |s| s.diverged.is_some());
        assert!(st.paused, "paused after divergence");
        let msg = st.diverged.unwrap_or_default();
        assert!(msg.contains("last good state"), "{msg}");
        let steps = st.steps;
        std::thread::sleep(Duration::from_millis(200));
        assert_eq!(lock(&shared.status).steps, steps, "no steps after divergence");
        assert!(lock(&shared.published).frames.is_some(), "the last set is still there to draw");
        tx.send(Control::Quit).expect("send");
        handle.join().expect("thread ends");
    });
}

/// Reset after the relaxation goes straight back to the relaxed state at t = 0 (the state kept when
/// the relaxation ended), without relaxing again: the status shows t = 0 and the step count of the
/// relaxation's end at once, never a negative time; the object poses are those of t = 0 again, and
/// the run steps on from there. On both back-ends (the GPU's restore is a keyframe upload).
#[test]
fn reset_after_the_relaxation_restores_the_relaxed_state() {
    on_both_back_ends("reset_after_the_relaxation_restores_the_relaxed_state", reset_restores);
}

/// Runs `f` with the simulation on the CPU, then on the GPU of the test adapter.
fn on_both_back_ends(name: &str, f: fn(perfuse::sim::gpu::GpuContext, bool)) {
    gpu_test(name, |ctx| {
        for use_gpu in [false, true] {
            f(ctx.clone(), use_gpu);
        }
    });
}

/// The block scene with a relaxation of a few steps (Δt ≈ 1.3e-5 s).
fn briefly_relaxed_block() -> Scenario {
    common::scenes::perfused_block()
        .with_override("relaxation=Some(Relaxation(duration: 4e-5, damping: 20.0, gravity_solid_only: true))")
        .expect("valid")
}

fn reset_restores(ctx: perfuse::sim::gpu::GpuContext, use_gpu: bool) {
    let sc = briefly_relaxed_block();
    let (tx, rx) = std::sync::mpsc::channel();
    let shared = Arc::new(Shared::default());
    let handle = spawn(ctx, use_gpu, sc, true, None, rx, shared.clone()).expect("thread");
    wait_for(&shared, "first publish", |s| s.publishes >= 1);
    // single steps until the relaxation has ended (each waits for the thread to settle)
    let mut k = 0;
    let relaxed = loop {
        k += 1;
        assert!(k < 50, "the relaxation does not end");
        tx.send(Control::Step).expect("send");
        wait_for(&shared, "one step", |s| s.steps == k);
        std::thread::sleep(Duration::from_millis(100));
        let st = lock(&shared.status).clone();
        if k == 1 {
            assert!(st.relaxing && st.t < 0.0, "the first step relaxes: {st:?}");
        }
        if !st.relaxing {
            break st;
        }
    };
    let steps_relaxed = relaxed.steps;
    let pose_at_0 = lock(&shared.published).info.objects.iter().map(|o| o.centre).collect::<Vec<_>>();
    // step on, move the tool, then reset
    tx.send(Control::Sim(Command::PlaceObject { object: 1, position: [0.0035, 0.003, 0.0055] })).expect("send");
    tx.send(Control::Pause(false)).expect("send");
    wait_for(&shared, "steps after t = 0", |s| s.steps >= steps_relaxed + 3);
    tx.send(Control::Pause(true)).expect("send");
    std::thread::sleep(Duration::from_millis(100));
    let moved = lock(&shared.published).info.objects.iter().map(|o| o.centre).collect::<Vec<_>>();
    assert_ne!(moved, pose_at_0, "the tool was moved");
    let publishes = lock(&shared.status).publishes;
    tx.send(Control::Reset).expect("send");
    let back = wait_for(&shared, "the reset", |s| s.steps == steps_relaxed);
    assert!(back.t.abs() < 1e-12 && !back.relaxing && back.paused, "{back:?}");
    let start = Instant::now();
    while lock(&shared.status).publishes <= publishes {
        assert!(start.elapsed() < Duration::from_secs(30), "the reset state was not published");
        std::thread::sleep(Duration::from_millis(20));
    }
    let pose = lock(&shared.published).info.objects.iter().map(|o| o.centre).collect::<Vec<_>>();
    assert_eq!(pose, pose_at_0, "the tools are back where they were at t = 0");
    // it does not relax again, and runs on from t = 0
    tx.send(Control::Step).expect("send");
    let on = wait_for(&shared, "a step after the reset", |s| s.steps == steps_relaxed + 1);
    assert!(on.t > 0.0 && !on.relaxing, "{on:?}");
    eprintln!(
        "reset ({}): back to t = 0 at step {steps_relaxed} without the relaxation's {steps_relaxed} steps; \
         one step on: t = {:.3e} s",
        on.backend, on.t
    );
    tx.send(Control::Quit).expect("send");
    handle.join().expect("thread ends");
}

/// The live run's pace (issue 5 §1, "or at a chosen real-time factor"): under `Control::Pace(r)`
/// the simulated clock advances by no more than r × the wall time (plus one batch: a batch is cut to
/// what the pace allows in 30 ms, at least one step), and it still advances; the status reports the
/// pace and `Pace(None)` lifts it. The bound is one-sided, so a slow machine cannot fail it.
#[test]
fn a_paced_run_keeps_to_its_real_time_factor() {
    gpu_test("a_paced_run_keeps_to_its_real_time_factor", |ctx| {
        let sc = common::scenes::perfused_block();
        let (tx, rx) = std::sync::mpsc::channel();
        let shared = Arc::new(Shared::default());
        let handle = spawn(ctx, false, sc, true, None, rx, shared.clone()).expect("thread");
        wait_for(&shared, "first publish", |s| s.publishes >= 1);
        let pace = 2e-4;
        tx.send(Control::Pace(Some(pace))).expect("send");
        wait_for(&shared, "pace set", |s| s.pace == Some(pace));
        tx.send(Control::Pause(false)).expect("send");
        let first = wait_for(&shared, "running", |s| s.steps >= 1);
        let (t_a, wall_a) = (first.t, Instant::now());
        let dt = first.dt.max(first.t / first.steps.max(1) as f64);
        let later = wait_for(&shared, "three more steps", |s| s.steps >= first.steps + 3);
        std::thread::sleep(Duration::from_millis(500));
        let st = lock(&shared.status).clone();
        let wall = wall_a.elapsed().as_secs_f64();
        let allowed = pace * wall + (pace * 0.03).max(dt) * 2.0;
        eprintln!(
            "paced at {pace}: {:.3e} s simulated in {wall:.2} s of wall time (allowed {allowed:.3e}; Δt {dt:.2e}, \
             {} steps, real-time factor shown {:.2e})",
            st.t - t_a,
            st.steps - first.steps,
            st.real_time_factor
        );
        assert!(later.t > t_a, "the paced run advances");
        assert!(st.t - t_a <= allowed, "ran ahead of its pace: {} s in {wall} s", st.t - t_a);
        tx.send(Control::Pace(None)).expect("send");
        wait_for(&shared, "pace lifted", |s| s.pace.is_none());
        tx.send(Control::Quit).expect("send");
        handle.join().expect("thread ends");
    });
}

/// The viewer's replay mode (issue 8 §2) and live recording (§1) without a window: record a live
/// session with the record control (it starts with a keyframe), replay it in the thread to its end
/// (pausing there), seek back, take over with a branch recording, drive the tool live, and check
/// that the branch names its parent, starts from a keyframe and replays bit-identically to the live
/// branch's final state.
#[test]
fn replay_mode_seeks_and_takes_over_with_a_branch() {
    use perfuse::app::sim_thread::{Start, spawn_with};
    use perfuse::replay::format::{ChunkKind, read_recording_file};
    use perfuse::replay::session::replay;
    use perfuse::sim::BackendKind;
    gpu_test("replay_mode_seeks_and_takes_over_with_a_branch", |ctx| {
        let dir = std::env::temp_dir().join(format!("perfuse-simthread-{}", std::process::id()));
        let (parent, branch) = (dir.join("live.pfrec"), dir.join("branch.pfrec"));
        let sc = common::scenes::perfused_block();

        // Live: a few steps, then record from the middle of the session.
        let (tx, rx) = std::sync::mpsc::channel();
        let shared = Arc::new(Shared::default());
        let start = Start {
            use_gpu: false,
            scenario: sc.clone(),
            paused: true,
            record: None,
            replay: None,
            relaxed_cache: None,
            fresh_relaxation: false,
        };
        let handle = spawn_with(ctx.clone(), start, rx, shared.clone()).expect("thread");
        wait_for(&shared, "first publish", |s| s.publishes >= 1);
        for _ in 0..3 {
            tx.send(Control::Step).expect("send");
        }
        wait_for(&shared, "three steps", |s| s.steps == 3);
        tx.send(Control::Record(Some(parent.clone()))).expect("send");
        wait_for(&shared, "recording", |s| s.recording.is_some());
        tx.send(Control::Sim(Command::PlaceObject { object: 1, position: [0.0035, 0.003, 0.0052] })).expect("send");
        for _ in 0..20 {
            tx.send(Control::Step).expect("send");
        }
        wait_for(&shared, "23 steps", |s| s.steps == 23);
        tx.send(Control::Record(None)).expect("send");
        wait_for(&shared, "recording finished", |s| s.recording.is_none());
        tx.send(Control::Quit).expect("send");
        handle.join().expect("thread ends");
        let rec = read_recording_file(&parent).expect("recording");
        assert!(rec.is_clean(), "{:?}", rec.warnings);
        assert_eq!(rec.chunks.first().map(|c| (c.kind, c.step)), Some((ChunkKind::Keyframe, 3)));
        let end_t = rec.last_t_s();

        // Replay it in the thread: plays to the end and pauses there.
        let (tx, rx) = std::sync::mpsc::channel();
        let shared = Arc::new(Shared::default());
        let start = Start {
            use_gpu: false,
            scenario: sc,
            paused: false,
            record: None,
            replay: Some(rec.clone()),
            relaxed_cache: None,
            fresh_relaxation: false,
        };
        let handle = spawn_with(ctx, start, rx, shared.clone()).expect("thread");
        let st = wait_for(&shared, "end of the replay", |s| s.replay.as_ref().is_some_and(|r| r.at_end) && s.paused);
        assert_eq!(st.steps, 23, "{st:?}");
        // A tool command is refused while replaying.
        tx.send(Control::Sim(Command::SetGravity([0.0; 3]))).expect("send");
        wait_for(&shared, "refusal", |s| s.error.as_deref().is_some_and(|e| e.contains("take over")));
        // The timeline seeks by step (exact), the API also by time.
        tx.send(Control::SeekStep(17)).expect("send");
        wait_for(&shared, "seek to step 17", |s| s.steps == 17);
        // Seek back to the middle, then take over with a branch and drive the tool.
        tx.send(Control::Seek(0.5 * end_t)).expect("send");
        let st = wait_for(&shared, "seek", |s| s.steps < 17 && s.steps >= 3);
        let taken_at = st.steps;
        tx.send(Control::TakeOver(Some(branch.clone()))).expect("send");
        wait_for(&shared, "live", |s| s.replay.is_none() && s.recording.is_some());
        tx.send(Control::Sim(Command::MoveObject { object: 1, target: [0.003, 0.0045, 0.0047], speed: 0.05 }))
            .expect("send");
        for _ in 0..8 {
            tx.send(Control::Step).expect("send");
        }
        wait_for(&shared, "live steps", |s| s.steps == taken_at + 8);
        tx.send(Control::Quit).expect("send");
        handle.join().expect("thread ends");

        let b = read_recording_file(&branch).expect("branch");
        assert!(b.is_clean(), "{:?}", b.warnings);
        let p = b.header.parent.as_ref().expect("names its parent");
        assert_eq!((p.step, p.hash_of_parent_header), (taken_at, rec.header.header_hash()));
        assert_eq!(b.chunks.first().map(|c| c.kind), Some(ChunkKind::Keyframe));
        let out = replay(&b, BackendKind::Cpu, true).expect("branch replays");
        assert!(out.hashes_checked >= 2 && out.mismatches.is_empty(), "{out:?}");
        assert_eq!(out.steps, taken_at + 8);
        let _ = std::fs::remove_dir_all(&dir);
    });
}

/// The viewer's cache of relaxed states (`replay::relaxed_cache`): the first launch relaxes live and
/// keeps the state at t = 0 on disk; the next launch of the same scenario starts there — at t = 0
/// with the relaxation's steps counted, not relaxing, the panel naming the kept file — and a
/// recording made by it starts with a keyframe of that state and replays with every hash equal;
/// `--fresh-relaxation` relaxes live again; a run whose tool was moved while it relaxed keeps nothing.
/// Both back-ends.
#[test]
fn a_second_launch_starts_from_the_kept_relaxed_state() {
    on_both_back_ends("a_second_launch_starts_from_the_kept_relaxed_state", second_launch);
}

fn second_launch(ctx: perfuse::sim::gpu::GpuContext, use_gpu: bool) {
    use perfuse::app::sim_thread::{Start, spawn_with};
    use perfuse::replay::format::{ChunkKind, read_recording_file};
    use perfuse::replay::relaxed_cache::{Engine, RelaxedCache};
    use perfuse::replay::session::replay;
    use perfuse::sim::{BackendKind, Simulation};
    let dir = std::env::temp_dir().join(format!("perfuse-relaxed-launch-{}-{use_gpu}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let cache = RelaxedCache::new(dir.join("cache"));
    let sc = briefly_relaxed_block();
    let build = || Simulation::with_gpu(&sc, use_gpu.then(|| ctx.clone())).expect("sim");
    let file = cache.path_for(&sc, &Engine::of(&build()));
    let launch = |cache: &RelaxedCache, fresh: bool, record: Option<std::path::PathBuf>| {
        let (tx, rx) = std::sync::mpsc::channel();
        let shared = Arc::new(Shared::default());
        let start = Start {
            use_gpu,
            scenario: sc.clone(),
            paused: true,
            record,
            replay: None,
            relaxed_cache: Some(cache.clone()),
            fresh_relaxation: fresh,
        };
        let handle = spawn_with(ctx.clone(), start, rx, shared.clone()).expect("thread");
        wait_for(&shared, "first publish", |s| s.publishes >= 1);
        (tx, shared, handle)
    };
    // first launch: relaxes live, step by step, and keeps the state
    let (tx, shared, handle) = launch(&cache, false, None);
    assert!(lock(&shared.status).relaxed_from.is_none());
    let mut k = 0;
    let steps_relaxed = loop {
        k += 1;
        assert!(k < 50, "the relaxation does not end");
        tx.send(Control::Step).expect("send");
        let st = wait_for(&shared, "one step", |s| s.steps == k);
        assert!(k > 1 || st.relaxing, "the first launch relaxes: {st:?}");
        std::thread::sleep(Duration::from_millis(50));
        if !lock(&shared.status).relaxing {
            break k;
        }
    };
    let start = Instant::now();
    while !file.exists() {
        assert!(start.elapsed() < Duration::from_secs(60), "{} was not written", file.display());
        std::thread::sleep(Duration::from_millis(20));
    }
    tx.send(Control::Quit).expect("send");
    handle.join().expect("thread ends");
    // the kept state is the one a headless relaxation (`Simulation::relax`) reaches, bit for bit
    let mut kept = build();
    cache.restore(&sc, &mut kept).expect("readable").expect("kept");
    let mut headless = build();
    headless.relax(|_| {}).expect("relax");
    assert_eq!(kept.stats().steps, headless.stats().steps);
    assert_eq!(
        kept.read_state().expect("state").hash(),
        headless.read_state().expect("state").hash(),
        "the viewer's live relaxation and a headless one end in the same state"
    );

    // second launch, recording: starts at t = 0 from the kept state
    let rec_path = dir.join("from-cache.pfrec");
    let (tx, shared, handle) = launch(&cache, false, Some(rec_path.clone()));
    let st = lock(&shared.status).clone();
    assert_eq!(st.steps, steps_relaxed, "{st:?}");
    assert!(st.t.abs() < 1e-12 && !st.relaxing && st.error.is_none(), "{st:?}");
    assert_eq!(st.relaxed_from.as_deref(), Some(file.display().to_string().as_str()));
    for _ in 0..3 {
        tx.send(Control::Step).expect("send");
    }
    let on = wait_for(&shared, "three steps", |s| s.steps == steps_relaxed + 3);
    assert!(on.t > 0.0 && !on.relaxing, "{on:?}");
    tx.send(Control::Quit).expect("send");
    handle.join().expect("thread ends");
    let rec = read_recording_file(&rec_path).expect("recording");
    assert!(rec.is_clean(), "{:?}", rec.warnings);
    assert_eq!(rec.chunks.first().map(|c| (c.kind, c.step)), Some((ChunkKind::Keyframe, steps_relaxed)));
    let backend = if use_gpu { BackendKind::Gpu } else { BackendKind::Cpu };
    let out = replay(&rec, backend, true).expect("replays");
    assert!(out.hashes_checked >= 1 && out.mismatches.is_empty(), "{out:?}");
    assert_eq!(out.steps, steps_relaxed + 3);

    // --fresh-relaxation: relaxes live again
    let (tx, shared, handle) = launch(&cache, true, None);
    let st = lock(&shared.status).clone();
    assert!(st.steps == 0 && st.relaxed_from.is_none(), "{st:?}");
    tx.send(Control::Step).expect("send");
    let st = wait_for(&shared, "one step", |s| s.steps == 1);
    assert!(st.relaxing && st.t < 0.0, "{st:?}");
    tx.send(Control::Quit).expect("send");
    handle.join().expect("thread ends");
    // a run the user changed while it relaxed (the tool moved) keeps nothing: its state is not the
    // scenario's relaxed state
    let cache2 = RelaxedCache::new(dir.join("cache2"));
    let (tx, shared, handle) = launch(&cache2, false, None);
    tx.send(Control::Step).expect("send");
    wait_for(&shared, "one step", |s| s.steps == 1 && s.relaxing);
    tx.send(Control::Sim(Command::PlaceObject { object: 1, position: [0.0035, 0.003, 0.0055] })).expect("send");
    for k in 2..=steps_relaxed + 1 {
        tx.send(Control::Step).expect("send");
        wait_for(&shared, "a step", |s| s.steps == k);
    }
    std::thread::sleep(Duration::from_millis(300));
    assert!(!lock(&shared.status).relaxing, "the relaxation ended");
    tx.send(Control::Quit).expect("send");
    handle.join().expect("thread ends");
    assert!(!cache2.path_for(&sc, &Engine::of(&build())).exists(), "a changed relaxation was kept");

    eprintln!("relaxed cache: the second launch skipped {steps_relaxed} relaxation steps ({})", file.display());
    let _ = std::fs::remove_dir_all(&dir);
}
