//! The warnings and errors a test binary logs, caught by a global `tracing` subscriber (headless apps
//! have no `LogPlugin`, so nothing else listens). Tests that read them hold [`serial`] so that their
//! lines do not mix.

use std::fmt::Debug;
use std::sync::{Mutex, MutexGuard, Once};

use bevy::log::tracing::field::{Field, Visit};
use bevy::log::tracing::{self, Event, Level, Metadata, Subscriber, span};

static LINES: Mutex<Vec<(Level, String)>> = Mutex::new(Vec::new());
static SERIAL: Mutex<()> = Mutex::new(());
static INSTALL: Once = Once::new();

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

/// Installs the recorder (once per binary) and gives the caller the log to itself until the guard drops;
/// the lines logged so far are discarded.
pub fn serial() -> MutexGuard<'static, ()> {
    INSTALL.call_once(|| {
        tracing::subscriber::set_global_default(Recorder).expect("no other global subscriber in this test binary");
    });
    let guard = SERIAL.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    take();
    guard
}

/// The warnings and errors logged since the last call, with their messages.
pub fn take() -> Vec<(Level, String)> {
    std::mem::take(&mut *LINES.lock().unwrap_or_else(|poisoned| poisoned.into_inner()))
}
