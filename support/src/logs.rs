//! The warnings and errors a test binary logs, caught by a global `tracing` subscriber (headless apps
//! have no `LogPlugin`, so nothing else listens).
//!
//! A test that reads them holds [`serial`]: it then has the log to itself. Apps log from Bevy's task
//! pools, which every app of the process shares, so a line cannot be traced to its test; instead every
//! [`headless`](crate::headless) app of another test holds a [`LogShared`] turn while it lives, and
//! [`serial`] waits until none does (and new ones wait until it is done).

use std::cell::Cell;
use std::fmt::Debug;
use std::sync::{Condvar, Mutex, MutexGuard, Once};

use bevy::prelude::{App, Resource};

use bevy::log::tracing::field::{Field, Visit};
use bevy::log::tracing::{self, Event, Level, Metadata, Subscriber, span};

static LINES: Mutex<Vec<(Level, String)>> = Mutex::new(Vec::new());
static INSTALL: Once = Once::new();

/// Who has the log: how many apps share it, and whether a test has it to itself.
struct Turns {
    sharing: usize,
    alone: bool,
}

static TURNS: Mutex<Turns> = Mutex::new(Turns { sharing: 0, alone: false });
static TURN_CHANGED: Condvar = Condvar::new();

thread_local! {
    /// Whether this thread's test holds [`serial`] (its own apps then take no shared turn).
    static HOLDS_THE_LOG: Cell<bool> = const { Cell::new(false) };
    /// How many shares this thread's apps hold (a test that holds one cannot wait for none).
    static SHARES_HERE: Cell<usize> = const { Cell::new(0) };
}

fn turns() -> MutexGuard<'static, Turns> {
    TURNS.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Records every warning and error with its message.
struct Recorder;

struct Message(String);

impl Visit for Message {
    fn record_debug(&mut self, field: &Field, value: &dyn Debug) {
        if field.name() == "message" {
            self.0 = format!("{value:?}");
        }
    }
}

impl Subscriber for Recorder {
    fn enabled(&self, metadata: &Metadata<'_>) -> bool {
        *metadata.level() <= Level::WARN
    }

    fn new_span(&self, _: &span::Attributes<'_>) -> span::Id {
        span::Id::from_u64(1)
    }

    fn record(&self, _: &span::Id, _: &span::Record<'_>) {}

    fn record_follows_from(&self, _: &span::Id, _: &span::Id) {}

    fn event(&self, event: &Event<'_>) {
        let mut message = Message(String::new());
        event.record(&mut message);
        LINES.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).push((*event.metadata().level(), message.0));
    }

    fn enter(&self, _: &span::Id) {}

    fn exit(&self, _: &span::Id) {}
}

/// The log to one test, until dropped: see [`serial`].
#[must_use = "the log is the test's only while the guard lives"]
pub struct LogToItself(());

impl Drop for LogToItself {
    fn drop(&mut self) {
        HOLDS_THE_LOG.with(|holds| holds.set(false));
        turns().alone = false;
        TURN_CHANGED.notify_all();
    }
}

/// Installs the recorder (once per binary) and gives the caller the log to itself until the guard drops,
/// once no other test's app is alive; the lines logged so far are discarded.
///
/// # Panics
/// If an app made on this thread is still alive: it holds a share the call would wait for forever. Take
/// the log before making the test's apps.
pub fn serial() -> LogToItself {
    assert_eq!(
        SHARES_HERE.with(Cell::get),
        0,
        "logs::serial() after this test made an app that is still alive: take the log first"
    );
    INSTALL.call_once(|| {
        tracing::subscriber::set_global_default(Recorder).expect("no other global subscriber in this test binary");
    });
    let mut turns = turns();
    while turns.alone || turns.sharing > 0 {
        turns = TURN_CHANGED.wait(turns).unwrap_or_else(|poisoned| poisoned.into_inner());
    }
    turns.alone = true;
    drop(turns);
    HOLDS_THE_LOG.with(|holds| holds.set(true));
    take();
    LogToItself(())
}

/// An app's share of the log, held as a resource while the app lives: see the module's docs.
#[derive(Resource)]
pub struct LogShared(());

impl Drop for LogShared {
    fn drop(&mut self) {
        SHARES_HERE.with(|shares| shares.set(shares.get().saturating_sub(1)));
        turns().sharing -= 1;
        TURN_CHANGED.notify_all();
    }
}

/// Gives `app`, made on this thread, a share of the log for as long as it lives, as soon as no test has
/// the log to itself: none if this thread's test holds [`serial`] (its app's lines are what it reads).
pub fn share_with(app: &mut App) {
    if HOLDS_THE_LOG.with(Cell::get) {
        return;
    }
    let mut turns = turns();
    while turns.alone {
        turns = TURN_CHANGED.wait(turns).unwrap_or_else(|poisoned| poisoned.into_inner());
    }
    turns.sharing += 1;
    drop(turns);
    SHARES_HERE.with(|shares| shares.set(shares.get() + 1));
    app.insert_resource(LogShared(()));
}

/// The warnings and errors logged since the last call, with their messages.
pub fn take() -> Vec<(Level, String)> {
    std::mem::take(&mut *LINES.lock().unwrap_or_else(|poisoned| poisoned.into_inner()))
}
