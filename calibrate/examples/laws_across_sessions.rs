//! Which of a differential drive's rival laws carries to another session: within each
//! month of the real differential robot (`shared/real/sessions/`: June, 23 June squares
//! with 25 June circles and Ivanjko paths, 14 sessions; December, 23 December, 15
//! sessions), each session is left out in turn. `calibrate` is run on the month's other
//! sessions with its defaults (its own choice), then with each law held at the value it
//! fitted there on its own (`law_tests`: the turn law, the speed law) and with none
//! (`--turn-law 0`); each dead-reckons the left-out session's runs from their first row
//! (applying its law, as a board that stores it would). Prints a markdown table (mean
//! RMS per session, mm) and the geometric mean of each over no law.
//!
//!     cargo run --release -p calibrate --features examples --example laws_across_sessions [-- --sessions DIR]

#[path = "../tests/support/proxy.rs"]
mod proxy;

fn main() {
    let dir = proxy::sessions_dir_from_args();
    let t0 = std::time::Instant::now();
    let folds = proxy::laws_across_sessions(&dir).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1)
    });
    println!(
        "| month | left-out session | runs | none (mm) | turn law (eb_arc/eb) | speed law (per m/s) | calibrate's choice |"
    );
    println!("|---|---|---|---|---|---|---|");
    for f in &folds {
        println!(
            "| {} | {} | {} | {:.2} | {:.2} ({:+.4}) | {:.2} ({:+.4}) | {:.2} |",
            f.month,
            f.session,
            f.runs,
            f.none_m * 1e3,
            f.turn_m * 1e3,
            f.laws.0,
            f.speed_m * 1e3,
            f.laws.1,
            f.chosen_m * 1e3
        );
    }
    let g = |m: fn(&proxy::LawFold) -> f64| proxy::geometric_mean_over_none(&folds, m);
    println!(
        "\ngeometric mean over no law: turn law {:.3}, speed law {:.3}, calibrate's choice {:.3}; the turn law better on {} of {} sessions",
        g(|f| f.turn_m),
        g(|f| f.speed_m),
        g(|f| f.chosen_m),
        folds.iter().filter(|f| f.turn_m < f.speed_m).count(),
        folds.len()
    );
    eprintln!("total {:.1} s", t0.elapsed().as_secs_f64());
}
