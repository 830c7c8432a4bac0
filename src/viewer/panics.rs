//! A panic on one of the viewer's threads becomes a message: never a hang, never a pane that
//! stays empty without a word.
//!
//! Every thread the viewer starts (the solver, a mesh solve, the display builds, the reference,
//! the artifact measurements) runs its work through [`catching`]. A panic unwinds to it and
//! comes back as the thread's answer:
//!
//! ```text
//!   "radlab-display" ── build panics ──► catching ──► Err("the display thread panicked at
//!                                                         src/….rs:L:C: <message>")
//!        │                                                      │ sent as the build's answer
//!        └─ goes on with the next request                       ▼
//!   UI: status bar + error list; a scripted run (--screenshot) exits 1 with it as its error
//! ```
//!
//! Where the panic happened comes from the hook [`install_hook`] sets (the windowed viewer sets
//! it): inside [`catching`] it notes the location instead of printing, so a scripted run's
//! stderr has the message once, as one line; anywhere else it hands over to the hook it
//! replaced. Without it (the tests) the message has no location and Rust's default hook prints
//! as usual.

use std::any::Any;
use std::cell::{Cell, RefCell};
use std::panic::{AssertUnwindSafe, catch_unwind};

thread_local! {
    /// How many [`catching`] calls this thread is inside (the hook stays quiet within one).
    static CATCHING: Cell<u32> = const { Cell::new(0) };
    /// Where the last panic caught on this thread happened ("file:line:column"), from the hook.
    static LOCATION: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// The text of a panic's payload (`panic!("…")` carries a `&str` or a `String`).
#[must_use]
pub fn panic_message(payload: &(dyn Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".to_owned())
}

/// Run `f`; a panic in it becomes `Err("the {thread} thread panicked[ at LOCATION]: MESSAGE")`.
///
/// What `f` was changing may be left half done: a caller keeps nothing `f` was building, and
/// gives up state that `f` was mutating (the solver thread ends after its answer).
pub fn catching<T>(thread: &str, f: impl FnOnce() -> T) -> Result<T, String> {
    CATCHING.with(|c| c.set(c.get() + 1));
    let result = catch_unwind(AssertUnwindSafe(f));
    CATCHING.with(|c| c.set(c.get().saturating_sub(1)));
    result.map_err(|payload| {
        let message = panic_message(&*payload);
        match LOCATION.with(|l| l.borrow_mut().take()) {
            Some(at) => format!("the {thread} thread panicked at {at}: {message}"),
            None => format!("the {thread} thread panicked: {message}"),
        }
    })
}

/// Set the panic hook described in the module docs (once per process; later calls do nothing).
/// With `RUST_BACKTRACE` set, caught panics are printed by the replaced hook too.
pub fn install_hook() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if CATCHING.with(Cell::get) > 0 {
                LOCATION.with(|l| *l.borrow_mut() = info.location().map(ToString::to_string));
                if std::env::var_os("RUST_BACKTRACE").is_none_or(|v| v == "0") {
                    return;
                }
            }
            previous(info);
        }));
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_a_message_naming_the_thread() {
        assert_eq!(catching("display", || 7), Ok(7));
        let e =
            catching("display", || -> u32 { panic!("slice index starts at 1 but ends at 0") }).unwrap_err();
        assert!(e.starts_with("the display thread panicked"), "{e}");
        assert!(e.ends_with(": slice index starts at 1 but ends at 0"), "{e}");
        let n = 3;
        let e = catching("solver", || -> u32 { panic!("{n} elements") }).unwrap_err();
        assert!(e.starts_with("the solver thread panicked") && e.ends_with(": 3 elements"), "{e}");
        let e = catching("reference", || std::panic::panic_any(42u8)).unwrap_err();
        assert!(e.ends_with(": a panic without a message"), "{e}");
        // The thread goes on: the next call runs normally.
        assert_eq!(catching("display", || "next"), Ok("next"));
        assert_eq!(CATCHING.with(Cell::get), 0, "every scope left");
    }

    #[test]
    fn with_the_hook_the_message_says_where() {
        // The hook is the process's: a panic caught here is only noted, others print as before.
        install_hook();
        let line = line!() + 1;
        let e = catching("display", || -> u8 { panic!("here") }).unwrap_err();
        let at = format!("the display thread panicked at {}:{line}:", file!());
        assert!(e.starts_with(&at), "{e} (expected {at}…)");
        assert!(e.ends_with(": here"), "{e}");
    }
}
