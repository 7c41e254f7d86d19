//! Progress of long work on stderr, whatever stderr is: a spinner on a terminal, and
//! plain lines on a pipe or a log file (a silent minute reads as a hang: a
//! 505 MB recording printed nothing for 600 s). The plain form says what it is doing one
//! second into a stage, then every 10 s, so short runs stay quiet.

use std::io::IsTerminal;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// The first plain line comes this long into a stage.
pub const FIRST_LINE_AFTER: Duration = Duration::from_secs(1);
/// Then one line this often.
pub const LINE_EVERY: Duration = Duration::from_secs(10);

struct State {
    message: String,
    since: Instant,
    printed: bool,
    done: bool,
}

/// The plain form's state, shared with its printing thread.
type Shared = Arc<(Mutex<State>, Condvar)>;

/// A progress indicator; [`Progress::finish`] (or dropping it) clears it.
pub struct Progress {
    bar: Option<indicatif::ProgressBar>,
    plain: Option<(Shared, std::thread::JoinHandle<()>)>,
}

impl Progress {
    /// Starts showing `msg` with the elapsed time.
    pub fn start(msg: &str) -> Progress {
        if std::io::stderr().is_terminal() {
            let b = indicatif::ProgressBar::new_spinner();
            b.set_style(
                indicatif::ProgressStyle::with_template("{spinner} {msg} ({elapsed})")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
            );
            b.set_message(msg.to_string());
            b.enable_steady_tick(Duration::from_millis(200));
            return Progress {
                bar: Some(b),
                plain: None,
            };
        }
        let shared = Arc::new((
            Mutex::new(State {
                message: msg.to_string(),
                since: Instant::now(),
                printed: false,
                done: false,
            }),
            Condvar::new(),
        ));
        let s = shared.clone();
        let t0 = Instant::now();
        let thread = std::thread::spawn(move || {
            let (lock, cv) = &*s;
            let Ok(mut st) = lock.lock() else { return };
            loop {
                if st.done {
                    return;
                }
                let wait = if st.printed {
                    LINE_EVERY
                } else {
                    FIRST_LINE_AFTER.saturating_sub(st.since.elapsed())
                };
                let Ok((g, timeout)) = cv.wait_timeout(st, wait) else {
                    return;
                };
                st = g;
                if st.done {
                    return;
                }
                if timeout.timed_out() && st.since.elapsed() >= FIRST_LINE_AFTER {
                    eprintln!("{} ({:.0} s)", st.message, t0.elapsed().as_secs_f64());
                    st.printed = true;
                }
            }
        });
        Progress {
            bar: None,
            plain: Some((shared, thread)),
        }
    }

    /// A new stage.
    pub fn set_message(&self, msg: String) {
        if let Some(b) = &self.bar {
            b.set_message(msg);
        } else if let Some((s, _)) = &self.plain {
            let (lock, cv) = &**s;
            if let Ok(mut st) = lock.lock() {
                st.message = msg;
                st.since = Instant::now();
                st.printed = false;
                cv.notify_all();
            }
        }
    }

    /// Clears the indicator.
    pub fn finish(mut self) {
        self.stop();
    }

    fn stop(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
        if let Some((s, t)) = self.plain.take() {
            let (lock, cv) = &*s;
            if let Ok(mut st) = lock.lock() {
                st.done = true;
                cv.notify_all();
            }
            let _ = t.join();
        }
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.stop();
    }
}
