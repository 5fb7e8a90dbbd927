//! Two GPU runs of the same scene give bit-identical states (`State::hash`): no float atomics, a
//! canonical neighbour order, and a deterministic grid sort (STYLE §5.6).

mod common;

use common::gpu::gpu_test;
use common::scenes::perfused_block;
use perfuse::scenario::generate;
use perfuse::sim::gpu::GpuSolver;
use perfuse::sim::params::Params;

#[test]
fn two_gpu_runs_are_bit_identical() {
    gpu_test("two_gpu_runs_are_bit_identical", |ctx| {
        let sc = perfused_block();
        let g = generate(&sc);
        let mut hashes = Vec::new();
        for _ in 0..2 {
            let mut gpu = GpuSolver::with_context(ctx.clone(), Params::new(&sc, &g), &g).unwrap();
            for _ in 0..100 {
                gpu.step().unwrap();
            }
            hashes.push(gpu.read_state().unwrap().hash());
        }
        eprintln!("hashes {:016x} {:016x}", hashes[0], hashes[1]);
        assert_eq!(hashes[0], hashes[1]);
    });
}
