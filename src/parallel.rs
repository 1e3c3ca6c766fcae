//! How the passes over many strands use the machine: work spread over Bevy's compute pool (shared by the
//! hair–hair grid and the renderer's preparation), and memory asked for ahead of its use.

use bevy::ecs::batching::BatchingStrategy;
use bevy::tasks::ComputeTaskPool;

/// How a parallel query over the strands splits them when strands cost unequal amounts (contacts, levels
/// of detail): many small batches per thread, so that no thread waits long on another (two big batches
/// left the followers' placement 1.5 times as fast on two threads as on one; sixteen a thread, 1.8).
pub(crate) fn uneven_batches(per_thread: usize) -> BatchingStrategy {
    BatchingStrategy::new().batches_per_thread(per_thread)
}

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

/// Asks for every cache line of `items` to be brought close to the core, without waiting for them: a
/// pass over many strands calls this a few strands ahead, so that the misses of one strand's small arrays
/// (each behind its own pointer) overlap the work on the strands before it instead of following each other.
/// A hint only: it changes no value, and does nothing off x86-64.
pub(crate) fn prefetch<T>(items: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        const LINE: usize = 64;
        let start = items.as_ptr().cast::<i8>();
        for offset in (0..std::mem::size_of_val(items)).step_by(LINE) {
            // SAFETY: a prefetch reads nothing into the program and never faults, and `start + offset` stays
            // inside `items`; SSE, which the instruction needs, is part of every x86-64 CPU.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(offset)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = items;
}
