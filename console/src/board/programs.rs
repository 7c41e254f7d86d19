//! Motion on the board: test programs (UMBmark squares, omni paths) checked with the
//! board's own rule before they are sent, waiting for their end, driving a twist, and
//! the stop after Ctrl-C.

use crate::client::Client;
use anyhow::{bail, Result};
use calib_core::motion::{Direction, OmniPath};
use calib_core::protocol::{Mode, ProgramSpec, Status, Trials};
use calib_core::Twist;
use std::io::{Read, Write};
use std::time::{Duration, Instant};

/// After Ctrl-C: sends Stop, says so, and watches the board until every wheel is at rest
/// (or [`crate::stop::REST_TIMEOUT`] passes), so the message the user reads is true.
pub fn stop_after_interrupt<L: Read + Write>(
    c: &mut Client<L>,
) -> Result<crate::stop::Interrupted> {
    use crate::stop::{REST_RATE, REST_TIMEOUT};
    c.stop()?;
    eprintln!("\nCtrl-C: stopping the robot...");
    let t0 = Instant::now();
    while t0.elapsed() < REST_TIMEOUT {
        let Ok(s) = c.status() else { break };
        let idle = matches!(s.mode, Mode::Idle);
        // Commands at zero (the stop ramp has ended; an open-loop stepper has no measured
        // rate) and measured rates at rest.
        let still = |v: &[f32]| v.iter().all(|r| r.abs() < REST_RATE);
        if idle && still(&s.wheel_cmds) && still(&s.wheel_rates) {
            return Ok(crate::stop::Interrupted {
                came_to_rest_after: Some(t0.elapsed()),
            });
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(crate::stop::Interrupted {
        came_to_rest_after: None,
    })
}

/// Waits for a program to end, calling `on_status` now and then; returns the last status.
pub fn wait_program<L: Read + Write>(
    c: &mut Client<L>,
    limit: Duration,
    mut on_status: impl FnMut(&Status),
) -> Result<Status> {
    let t0 = Instant::now();
    let mut seen_busy = false;
    let _guard = crate::stop::Guard::new();
    loop {
        if crate::stop::requested() {
            return Err(stop_after_interrupt(c)?.into());
        }
        let s = c.status()?;
        on_status(&s);
        let idle = matches!(s.mode, Mode::Idle);
        if !idle {
            seen_busy = true;
        }
        // The board starts the program when it answers RunProgram, so idle right after
        // means it already finished (or was stopped).
        if idle && (seen_busy || t0.elapsed() > Duration::from_millis(200)) {
            return Ok(s);
        }
        if t0.elapsed() > limit {
            let _ = c.stop();
            bail!(
                "the program did not finish within {:.0} s; sent Stop",
                limit.as_secs_f64()
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Starts a UMBmark square.
pub fn run_umbmark<L: Read + Write>(
    c: &mut Client<L>,
    dir: Direction,
    side_m: f64,
    log_rate_hz: u16,
    link_timeout_ms: u16,
) -> Result<Duration> {
    start_program(
        c,
        ProgramSpec::Umbmark { side_m, dir },
        log_rate_hz,
        link_timeout_ms,
    )
}

/// Starts a circle.
pub fn run_circle<L: Read + Write>(
    c: &mut Client<L>,
    dir: Direction,
    radius_m: f64,
    laps: u8,
    log_rate_hz: u16,
    link_timeout_ms: u16,
) -> Result<Duration> {
    start_program(
        c,
        ProgramSpec::Circle {
            radius_m,
            dir,
            laps,
        },
        log_rate_hz,
        link_timeout_ms,
    )
}

/// Starts an omni path.
pub fn run_omni<L: Read + Write>(
    c: &mut Client<L>,
    path: OmniPath,
    length_m: f64,
    idle: calib_core::protocol::IdleWheels,
    log_rate_hz: u16,
    link_timeout_ms: u16,
) -> Result<Duration> {
    start_program(
        c,
        ProgramSpec::Omni {
            path,
            length_m,
            idle,
        },
        log_rate_hz,
        link_timeout_ms,
    )
}

/// Checks a program with the board's own rule ([`ProgramSpec::validate`] against the
/// board's robot and arena) before anything is sent, then starts it. Returns how long to
/// wait for it before giving up: a minute plus a minute per metre of its longest length,
/// which the check has bounded to the arena. The board stops the program when it hears
/// nothing from this host for `link_timeout_ms` (0: never; [`wait_program`]'s polling
/// keeps it alive).
pub fn start_program<L: Read + Write>(
    c: &mut Client<L>,
    program: ProgramSpec,
    log_rate_hz: u16,
    link_timeout_ms: u16,
) -> Result<Duration> {
    let params = c.params()?;
    let robot = &params.robot;
    let arena = params.safety.arena_m as f64;
    if let Err(why) = program.validate(robot.wheel_count(), robot.kind, arena) {
        bail!("not sent: {why} (the board's arena is {arena} m; `factors`/params set it)");
    }
    let longest = match &program {
        ProgramSpec::Umbmark { side_m, .. } => *side_m,
        ProgramSpec::Omni { length_m, .. } => *length_m,
        ProgramSpec::Custom(_) => arena,
        ProgramSpec::Circle { radius_m, laps, .. } => {
            core::f64::consts::TAU * radius_m * f64::from(*laps)
        }
    };
    // Say before the run which trials it will push out of the log (the board cannot tell
    // whether they were pulled).
    let (info, trials) = (c.info()?, c.trials()?);
    let gone = eviction_forecast(
        &trials,
        info.log_capacity,
        info.record_size,
        &program,
        &params.limits,
        log_rate_hz,
    );
    if !gone.is_empty() {
        let ids: Vec<String> = gone.iter().map(u16::to_string).collect();
        eprintln!(
            "note: this run will evict trial(s) {} from the board's log to make room (it keeps the last {} trials and as many records as fit); pull any you still need first (`wheelcal log pull`)",
            ids.join(", "),
            calib_core::protocol::MAX_TRIALS
        );
    }
    c.run_program(program, log_rate_hz, link_timeout_ms)?;
    Ok(program_time_limit(longest))
}

/// Trials (ids, oldest first) a program logging at `rate_hz` would push out of the
/// board's log: the ring evicts whole trials, oldest first, until the new records fit,
/// and the oldest one when the trial table is full. The program's length comes from the
/// board's own motion profile (`limits`), with 10 % to spare.
pub fn eviction_forecast(
    trials: &Trials,
    capacity: u32,
    record_size: u16,
    program: &ProgramSpec,
    limits: &calib_core::motion::ProfileLimits,
    rate_hz: u16,
) -> Vec<u16> {
    if rate_hz == 0 {
        return Vec::new();
    }
    let prog = program.program();
    let records = (prog.duration(limits) * 1.1 * f64::from(rate_hz)).ceil();
    // The log stores records compressed (about 4.3 bytes for a 32-byte two-wheel record):
    // the size that counts is the one the board's own trials show, the largest of them
    // (32 bytes a record named trials that were never evicted). Without a
    // trial to learn from, the uncompressed size bounds it.
    let per_record = trials
        .trials
        .iter()
        .filter(|t| t.records > 0)
        .map(|t| f64::from(t.bytes) / f64::from(t.records))
        .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))))
        .unwrap_or(f64::from(record_size))
        .min(f64::from(record_size));
    let needed = (records * per_record).min(f64::from(capacity));
    let mut used: f64 = trials.trials.iter().map(|t| f64::from(t.bytes)).sum();
    let mut gone = Vec::new();
    for t in &trials.trials {
        let table_full = trials.trials.len() - gone.len() >= calib_core::protocol::MAX_TRIALS;
        if f64::from(capacity) - used >= needed && !table_full {
            break;
        }
        used -= f64::from(t.bytes);
        gone.push(t.id);
    }
    gone
}

/// A minute plus a minute per metre, for any finite length (negative or NaN count as 0,
/// huge values saturate): never panics, whatever the number.
pub fn program_time_limit(length_m: f64) -> Duration {
    let s = 60.0 + 60.0 * length_m.max(0.0);
    Duration::try_from_secs_f64(s).unwrap_or(Duration::from_secs(24 * 3600))
}

/// Drives at a twist for a while, refreshing the command faster than the board's
/// command timeout, then stops.
pub fn drive_for<L: Read + Write>(
    c: &mut Client<L>,
    twist: Twist<f32>,
    duration: Duration,
) -> Result<()> {
    let _guard = crate::stop::Guard::new();
    let t0 = Instant::now();
    let mut refreshed = None::<Instant>;
    while t0.elapsed() < duration {
        if crate::stop::requested() {
            return Err(stop_after_interrupt(c)?.into());
        }
        if refreshed.is_none_or(|r| r.elapsed() >= Duration::from_millis(100)) {
            c.drive(twist, 0)?;
            refreshed = Some(Instant::now());
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    c.stop()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::protocol::{ProgramKind, TrialEnd, TrialInfo, MAX_TRIALS};
    use calib_core::Corrections;

    fn trial(id: u16, bytes: u32) -> TrialInfo {
        TrialInfo {
            id,
            program: ProgramKind::Drive,
            start_ms: 0,
            rate_hz: 50,
            wheel_count: 2,
            record_size: 32,
            records: bytes / 32,
            bytes,
            dropped: 0,
            end: TrialEnd::Completed,
            corrections: Corrections::None,
        }
    }

    #[test]
    fn a_run_names_the_trials_it_will_evict() {
        let limits = calib_core::motion::ProfileLimits::default();
        let square = ProgramSpec::Umbmark {
            side_m: 4.0,
            dir: Direction::Cw,
        };
        let secs =
            calib_core::motion::Program::umbmark_square(4.0, Direction::Cw).duration(&limits);
        // Bytes the square logs at 50 Hz, 32-byte records, with the 10 % margin.
        let need = (secs * 1.1 * 50.0).ceil() as u32 * 32;
        let list = |sizes: &[u32]| Trials {
            trials: sizes
                .iter()
                .enumerate()
                .map(|(i, &b)| trial(i as u16 + 1, b))
                .collect(),
            evicted: 0,
        };
        // Room enough: nothing goes.
        let cap = 3 * need;
        let f = |t: &Trials| eviction_forecast(t, cap, 32, &square, &limits, 50);
        assert!(f(&list(&[need, need / 2])).is_empty());
        // Full log: the oldest go until the run fits (trial 1 frees `need`).
        assert_eq!(f(&list(&[need, need, need / 2])), vec![1]);
        assert_eq!(f(&list(&[need / 2, need / 2, need * 2])), vec![1, 2]);
        // A full trial table evicts the oldest even with bytes to spare.
        let many = vec![8; MAX_TRIALS];
        assert_eq!(f(&list(&many)), vec![1]);
        // No logging, no eviction.
        assert!(eviction_forecast(&list(&[cap]), cap, 32, &square, &limits, 0).is_empty());
        // Compressed trials (43 bytes per 10 records): the run needs 4.3 / 32 of `need`,
        // so a log with that much free keeps every trial.
        let packed = |sizes: &[u32]| Trials {
            trials: sizes
                .iter()
                .enumerate()
                .map(|(i, &b)| TrialInfo {
                    records: b * 10 / 43,
                    ..trial(i as u16 + 1, b)
                })
                .collect(),
            evicted: 0,
        };
        let small = need * 43 / 320 + need / 100;
        assert!(f(&packed(&[cap - small])).is_empty());
        assert_eq!(f(&packed(&[cap - small / 2])), vec![1]);
    }
}
