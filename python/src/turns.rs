//! Requests from several Python threads take turns on one solid's engine, and a request
//! waiting for its turn can give up when its caller is interrupted (a plain lock cannot be left
//! while waiting for it).

use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// How often a request waiting behind another one looks whether its caller gave up (it is
/// woken at once when the other one ends).
const ENGINE_POLL: std::time::Duration = std::time::Duration::from_millis(10);

/// Requests take turns on a solid's engine: `busy` says one holds it, `released` wakes one
/// waiting request when it ends. (A plain lock cannot be given up while waiting for it.)
#[derive(Default)]
pub struct Turns {
    busy: Mutex<bool>,
    released: Condvar,
}

impl Turns {
    /// Wait for the turn; None as soon as `abandoned()` says the caller gave up.
    pub fn take(&self, abandoned: impl Fn() -> bool) -> Option<Turn<'_>> {
        let mut busy = lock(&self.busy);
        while *busy {
            if abandoned() {
                return None;
            }
            busy = self
                .released
                .wait_timeout(busy, ENGINE_POLL)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
        *busy = true;
        Some(Turn(self))
    }
}

/// A request's turn, given back when it is dropped.
pub struct Turn<'a>(&'a Turns);

impl Drop for Turn<'_> {
    fn drop(&mut self) {
        *lock(&self.0.busy) = false;
        self.0.released.notify_one();
    }
}
