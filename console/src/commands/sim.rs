//! `wheelcal sim-board`, `wheelcal sim record` and `wheelcal demo`.

use crate::args::{DemoArgs, SimBoardArgs, SimCmd, SimRecordArgs};
use crate::demo;
use crate::output::Output;
use crate::sim_board::{self, SimBoardOptions};
use anyhow::{Context, Result};
use calib_core::motion::Direction;
use formats::robot_file;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// A virtual board on a pseudo-terminal until Ctrl-C or SIGTERM.
pub fn sim_board(a: SimBoardArgs, out: Output) -> Result<()> {
    let opts = SimBoardOptions {
        robot: a.robot,
        link: a.link,
        seed: a.seed,
        speed: a.speed,
        effects: a.effect,
        roughness: a.roughness,
        turn_scrub: a.turn_scrub,
        flash: a.flash,
        truth: a.truth,
    };
    // Ctrl-C or SIGTERM ends the board cleanly (its link is removed).
    let _guard = crate::stop::Guard::new();
    let stop = Arc::new(AtomicBool::new(false));
    let s2 = stop.clone();
    std::thread::spawn(move || loop {
        if crate::stop::requested() {
            s2.store(true, Ordering::Relaxed);
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    });
    sim_board::run(&opts, stop, |ready| {
        let _ =
            out.emit(ready, || {
                format!(
                "virtual board ({}, seed {}) on {}{}\ntruth of each trial: {}\nCtrl-C to stop\n",
                ready.robot,
                ready.seed,
                ready.pty,
                ready.link.as_ref().map(|l| format!(" (link {l})")).unwrap_or_default(),
                ready.truth_file
            )
            });
        use std::io::Write;
        let _ = std::io::stdout().flush();
    })
}

/// Dispatches `sim` subcommands.
pub fn run(cmd: SimCmd, out: Output) -> Result<()> {
    match cmd {
        SimCmd::Record(a) => record(a, out),
    }
}

/// A simulated recording with hidden effects.
fn record(a: SimRecordArgs, out: Output) -> Result<()> {
    let robot = robot_file::load(&a.robot)?;
    let effects = a
        .effect
        .iter()
        .map(|e| sim::Effect::parse(e).with_context(|| format!("--effect {e}")))
        .collect::<Result<Vec<_>>>()?;
    let program = match (a.umbmark_side, a.circle_radius) {
        (Some(side), _) => Some(calib_core::motion::Program::umbmark_square(
            side,
            Direction::Ccw,
        )),
        (None, Some(radius)) => Some(calib_core::motion::Program::circle(
            radius,
            Direction::Ccw,
            1,
        )),
        (None, None) => None,
    };
    let motion = match program {
        Some(program) => sim::record::Motion::Program {
            program: Box::new(program),
            limits: Default::default(),
        },
        None => sim::record::Motion::Random(sim::record::RandomMotion {
            duration_s: a.duration,
            ..Default::default()
        }),
    };
    let mut cfg = sim::record::RecordConfig {
        row_rate_hz: a.rate,
        ..Default::default()
    };
    cfg.sim.seed = a.seed;
    if let Some(n) = a.vision_noise {
        cfg.sim.vision.sigma_xy_m = n;
    }
    let rec = sim::record::record(&robot, &effects, sim::Surface::flat(), &motion, &cfg)
        .context("cannot simulate the recording")?;
    rec.write_dir(&a.out)?;
    #[derive(serde::Serialize)]
    struct Written {
        out: String,
        rows: usize,
        effects: Vec<String>,
        seed: u64,
    }
    let w = Written {
        out: a.out.display().to_string(),
        rows: rec.recording.len(),
        effects: effects.iter().map(|e| e.to_string()).collect(),
        seed: a.seed,
    };
    out.emit(&w, || {
        format!(
            "wrote {} rows to {} (effects: {})\n",
            w.rows,
            w.out,
            if w.effects.is_empty() {
                "none".into()
            } else {
                w.effects.join(" ")
            }
        )
    })
}

/// The UMBmark procedure on a virtual board, before and after.
pub fn demo(a: DemoArgs, out: Output) -> Result<()> {
    let rep = demo::run(
        &a.robot,
        a.seed,
        a.runs,
        a.side,
        a.report.as_deref(),
        out == Output::Human,
        a.circle_radius.map(|r| (r, a.circle_laps)),
    )?;
    out.emit(&rep, || rep.human())
}
