//! Work spread over Bevy's compute pool, shared by the hair–hair grid and the renderer's preparation.

use bevy::tasks::ComputeTaskPool;

/// Runs `task` on every item of `work`, on Bevy's compute pool when it has `threads` > 1 threads.
pub(crate) fn run_in_parallel<W: Send>(threads: usize, work: impl Iterator<Item = W>, task: impl Fn(W) + Sync) {
    match ComputeTaskPool::try_get() {
        Some(pool) if threads > 1 => {
            let task = &task;
            pool.scope(|scope| {
                for item in work {
                    scope.spawn(async move { task(item) });
                }
            });
        }
        _ => work.for_each(task),
    }
}
