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
