//! Single board requests: `info`, `drive`, `status`, `stop`, `estop`, `clear-fault`.

use crate::args::DriveArgs;
use crate::board;
use crate::output::Output;
use crate::session::Ctx;
use anyhow::Result;
use calib_core::Twist;
use std::time::Duration;

/// `wheelcal info`.
pub fn info(ctx: &mut Ctx, out: Output) -> Result<()> {
    let r = board::info(ctx.client()?)?;
    out.emit(&r, || r.human())
}

/// `wheelcal drive`: the twist for a while, then stop (Ctrl-C stops at once).
pub fn drive(a: DriveArgs, ctx: &mut Ctx, out: Output) -> Result<()> {
    let client = ctx.client()?;
    board::drive_for(
        client,
        Twist::new(a.vx, a.vy, a.omega),
        Duration::from_secs_f64(a.duration),
    )?;
    let s = client.status()?;
    out.emit(&s, || format!("{}\n", board::status_line(&s)))
}

/// `wheelcal status [--follow]`.
pub fn status(follow: bool, period_ms: u16, ctx: &mut Ctx, out: Output) -> Result<()> {
    status_live(follow, period_ms, None, ctx, out)
}

/// `wheelcal status [--follow [--foxglove ADDR]]`: with `foxglove`, each telemetry sample
/// is also served to Foxglove on that address ([`crate::foxglove_live`]).
pub fn status_live(
    follow: bool,
    period_ms: u16,
    foxglove: Option<&str>,
    ctx: &mut Ctx,
    out: Output,
) -> Result<()> {
    if follow && foxglove.is_some() {
        // Before the board is opened: a wheelcal without the server says how to get one.
        crate::foxglove_live::require_built()?;
    }
    let client = ctx.client()?;
    let live = match (follow, foxglove) {
        (true, Some(a)) => {
            let addr = crate::foxglove_live::parse_addr(a)?;
            let robot = client.params()?.robot;
            let live = crate::foxglove_live::Live::start(addr, &robot)?;
            if !live.addr().ip().is_loopback() {
                out.note(&format!(
                    "--foxglove {}: not a loopback address, anyone who reaches this machine can watch the telemetry",
                    live.addr()
                ));
            }
            out.note(&format!(
                "foxglove: serving ws://{} (Foxglove: Open connection, Foxglove WebSocket)",
                live.addr()
            ));
            Some(live)
        }
        _ => None,
    };
    if !follow {
        let s = client.status()?;
        return out.emit(&s, || format!("{}\n", board::status_line(&s)));
    }
    let _guard = crate::stop::Guard::new();
    client.set_telemetry(period_ms.max(20))?;
    while !crate::stop::requested() {
        if let Some(s) = client.next_telemetry(Duration::from_millis(500))? {
            if let Some(l) = &live {
                l.publish(&s)?;
            }
            if !out.emit_more(&s, || format!("{}\n", board::status_line(&s)))? {
                break; // the reader has gone: stop the stream and free the port
            }
        }
    }
    client.set_telemetry(0)?;
    Ok(())
}

/// `wheelcal stop`.
pub fn stop(ctx: &mut Ctx, out: Output) -> Result<()> {
    ctx.client()?.stop()?;
    out.emit(&serde_json::json!({"stopped": true}), || "stopped\n".into())
}

/// `wheelcal estop`: through the wheelcal holding the port if there is one (woken first
/// if it is suspended), else on the port itself.
pub fn estop(ctx: &mut Ctx, out: Output) -> Result<()> {
    use crate::stop::{RelayOutcome, Via};
    // Another wheelcal may hold the port: it relays the E-stop at once.
    let route = match (&ctx.client, &ctx.port) {
        (None, Some(port)) => crate::stop::relay_estop(port)?,
        _ => crate::stop::EstopRoute {
            outcome: RelayOutcome::NotHeld,
            impostor_pid: None,
        },
    };
    if let Some(pid) = route.impostor_pid {
        eprintln!(
            "warning: process {pid} answers on the E-stop relay's name but does not hold the port: not trusted"
        );
    }
    let relayed = match &route.outcome {
        RelayOutcome::Relayed(r) => Some(*r),
        RelayOutcome::NotHeld => None,
        RelayOutcome::HolderGone(pid) => {
            eprintln!("note: the wheelcal holding the port (process {pid}) is gone; sending the E-stop on the port directly");
            None
        }
        RelayOutcome::HeldByOther { .. } => None,
    };
    if relayed.is_none() {
        let sent = ctx.client().and_then(|c| Ok(c.estop()?));
        if let (Err(e), RelayOutcome::HeldByOther { pid, name }) = (&sent, &route.outcome) {
            let port = ctx.port.as_deref().unwrap_or("the port");
            anyhow::bail!(
                "{port} is held by process {pid} ({name}), which is not a wheelcal and cannot relay the E-stop ({e:#}): stop the robot by hand, or end that process"
            );
        }
        sent?;
    }
    let ms = relayed.map(|r| r.elapsed.as_secs_f64() * 1e3);
    let woke = relayed.and_then(|r| r.woke_pid);
    let holder_gone = match route.outcome {
        RelayOutcome::HolderGone(pid) => Some(pid),
        _ => None,
    };
    let via = relayed.map(|r| match r.via {
        Via::Socket => "socket",
        Via::Signal => "signal",
    });
    let holder = relayed.and_then(|r| r.holder_pid);
    let verified = relayed.map(|r| r.verified);
    out.emit(
        &serde_json::json!({"estop": true, "relayed_ms": ms, "relayed_via": via, "holder_pid": holder,
            "holder_verified": verified, "woke_pid": woke, "holder_gone_pid": holder_gone,
            "impostor_pid": route.impostor_pid}),
        || {
            let Some(r) = relayed else {
                return "E-STOP latched: motors off (clear with `wheelcal clear-fault`)\n".into();
            };
            let who = match r.holder_pid {
                Some(pid) => format!("the wheelcal holding the port (process {pid})"),
                None => "the wheelcal holding the port".into(),
            };
            let how = match r.via {
                Via::Socket => "",
                Via::Signal => ", reached by signal",
            };
            let woke = match r.woke_pid {
                Some(_) => ": it was suspended, so it was woken with SIGCONT to relay it",
                None => "",
            };
            let unverified = if r.verified {
                ""
            } else {
                " (that it holds the port could not be checked: another user's process)"
            };
            format!(
                "E-STOP sent through {who}{how}{unverified} ({:.1} ms){woke}; motors off (clear with `wheelcal clear-fault`)\n",
                r.elapsed.as_secs_f64() * 1e3
            )
        },
    )
}

/// `wheelcal clear-fault`.
pub fn clear_fault(ctx: &mut Ctx, out: Output) -> Result<()> {
    ctx.client()?.clear_fault()?;
    out.emit(&serde_json::json!({"cleared": true}), || {
        "fault and E-stop cleared\n".into()
    })
}
