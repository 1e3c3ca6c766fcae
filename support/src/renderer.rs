//! Tests that start Bevy's renderer, or a wgpu device of their own, take turns.

use std::sync::{Mutex, MutexGuard};

static RENDERER: Mutex<()> = Mutex::new(());

/// Holds the test binary's renderer until the guard drops: take it before making the app, so that the app
/// is dropped first. Two rendering apps at once in one process sometimes read back a storage buffer as
/// zeros that the CPU had written (lavapipe, `tests/gpu/followers.rs`: 5 failing runs of 14 with the tests
/// in parallel, none of 6 one at a time); a game has one renderer. The strand step's tests, which make a
/// wgpu device of their own, take it too.
pub fn one_at_a_time() -> MutexGuard<'static, ()> {
    RENDERER.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}
