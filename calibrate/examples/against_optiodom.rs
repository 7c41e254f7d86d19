//! Issue 56 §3 on the differential robot's sessions (`shared/real/sessions/`):
//! `calibrate` against OptiOdom's objective re-implemented (`tests/support/proxy.rs`,
//! [`optiodom_fit`]: the three parameters by least squares on positions dead-reckoned from
//! each run's first pose, no resets, every 0.5 m of travel), both trained on the same
//! runs, for the issue's 20 training sets; each judged on every differential run it was
//! not trained on (the free-form runs the issue judges on are kept apart: this is the
//! proxy). Prints a markdown table: the board (factors and laws), the same calibration's
//! constant geometry, OptiOdom's objective, the ratios, and their geometric means.
//!
//!     cargo run --release -p calibrate --features examples --example against_optiodom [-- --sessions DIR]

#[path = "../tests/support/proxy.rs"]
mod proxy;

fn main() {
    let dir = proxy::sessions_dir_from_args();
    println!("| training runs | trained | judged | law kept | board (mm) | constant (mm) | OptiOdom's objective (mm) | board / OptiOdom | board / constant |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let (mut ln_opti, mut ln_const, mut n) = (0.0, 0.0, 0);
    let (mut worst_opti, mut worst_const) = (0.0f64, 0.0f64);
    let all = proxy::list_runs(&dir).unwrap_or_default();
    for (name, train) in proxy::issue56_training_sets() {
        let test = |r: &proxy::RunDir| !train(r);
        if !all.iter().any(|r| r.robot == "diff" && test(r)) {
            println!("| {name} | all | none: nothing is left to judge it on | | | | | | |");
            continue;
        }
        let r = match proxy::against_optiodom(&dir, &name, &*train, &test) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("{name}: {e}");
                std::process::exit(1);
            }
        };
        let (ro, rc) = (r.board_m / r.optiodom_m, r.board_m / r.constant_m);
        ln_opti += ro.ln();
        ln_const += rc.ln();
        n += 1;
        worst_opti = worst_opti.max(ro);
        worst_const = worst_const.max(rc);
        println!(
            "| {name} | {} | {} | {} | {:.1} | {:.1} | {:.1} | {ro:.3} | {rc:.3} |",
            r.train_runs,
            r.test_runs,
            r.law
                .map(|(l, v)| format!("{l} {v:+.4}"))
                .unwrap_or_else(|| "none".into()),
            r.board_m * 1e3,
            r.constant_m * 1e3,
            r.optiodom_m * 1e3
        );
    }
    let n = n.max(1) as f64;
    println!(
        "\ngeometric mean board / OptiOdom {:.3} (worst {worst_opti:.3}); board / constant {:.3} (worst {worst_const:.3}) over {n} sets",
        (ln_opti / n).exp(),
        (ln_const / n).exp()
    );
}
