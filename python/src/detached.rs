//! Long calls off the interpreter: the work runs on a scoped thread while the calling thread,
//! detached from Python, waits for it and looks at Python's signals between waits, so other
//! Python threads run meanwhile and Ctrl-C is answered (the request's cancellation token is
//! cancelled and the call raises KeyboardInterrupt once the work has stopped).

use crate::errors::{engine_err, Error};
use pyo3::prelude::*;
use std::any::Any;
use std::panic::{self, AssertUnwindSafe};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

/// How long the calling thread waits between looks at Python's signals: short enough for
/// Ctrl-C to feel immediate, long enough to cost nothing.
const POLL: Duration = Duration::from_millis(50);

/// What the worker thread hands back: its result, or the payload of its panic.
type Outcome<T> = std::thread::Result<solidsynth::Result<T>>;

/// Run `work` on a scoped thread, detached from the interpreter; on a pending signal (Ctrl-C
/// raises KeyboardInterrupt from `check_signals`) call `on_interrupt` once (it cancels the
/// work's token, where it has one), wait for the work to stop, and raise the signal's
/// exception. The thread is always joined before this returns: no work outlives the call.
///
/// Work without a token (the analysis, `eval`) cannot be stopped early: it finishes and then
/// the interrupt is raised.
pub fn run_detached<T, F>(py: Python<'_>, on_interrupt: impl Fn(), work: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> solidsynth::Result<T> + Send,
{
    let (sender, receiver) = mpsc::channel::<Outcome<T>>();
    std::thread::scope(|scope| {
        scope.spawn(move || {
            let outcome = panic::catch_unwind(AssertUnwindSafe(work));
            // The receiver lives until this scope ends, after the join: the send succeeds.
            let _ = sender.send(outcome);
        });
        let mut receiver = receiver;
        let mut interrupted: Option<PyErr> = None;
        let outcome = loop {
            // A `Receiver` is not `Sync`, so it is moved into the detached closure and back.
            let (back, got) = py.detach(move || {
                let got = receiver.recv_timeout(POLL);
                (receiver, got)
            });
            receiver = back;
            match got {
                Ok(outcome) => break outcome,
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => {
                    let lost: Box<dyn Any + Send> = Box::new("the worker thread ended early");
                    break Err(lost);
                }
            }
            if interrupted.is_none() {
                if let Err(signal) = py.check_signals() {
                    on_interrupt();
                    interrupted = Some(signal);
                }
            }
        };
        if let Some(signal) = interrupted {
            return Err(signal);
        }
        match outcome {
            Ok(result) => result.map_err(engine_err),
            Err(panic) => Err(Error::new_err(format!(
                "internal error: {}",
                panic_text(&*panic)
            ))),
        }
    })
}

/// The message of a panic's payload.
fn panic_text(payload: &(dyn Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "a panic without a message".to_string()
    }
}
