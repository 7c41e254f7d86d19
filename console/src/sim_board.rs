//! `wheelcal sim-board`: the virtual board on a pseudo-terminal.

use crate::link::PortStream;
use crate::virtual_board::{board_flash, TrialTruth, VirtualBoard};
use anyhow::{bail, Context, Result};
use formats::robot_file;
use sim::{Effect, SimConfig, SimRobot, Surface};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// What `sim-board` needs.
#[derive(Debug, Clone)]
pub struct SimBoardOptions {
    /// Robot description (docs/formats.md §1) the simulated robot is built from.
    pub robot: PathBuf,
    /// Symbolic link to point at the pseudo-terminal (a stable port name), if any.
    pub link: Option<PathBuf>,
    /// Seed of the simulation's random noise.
    pub seed: u64,
    /// Simulated seconds per wall-clock second; infinite = flat out while a program runs.
    pub speed: f64,
    /// Hidden faults, in the catalogue's `ID=name:value,...` form.
    pub effects: Vec<String>,
    /// Floor roughness (non-systematic error), metres of travel noise per sqrt(metre).
    pub roughness: f64,
    /// Tyre scrub: a differential drive's effective wheelbase (an omni robot's wheel
    /// distance from the centre) this much longer on arcs than in a turn in place
    /// (`SimConfig::turn_scrub`; 0: none).
    pub turn_scrub: f64,
    /// File mirroring the virtual board's flash, so saved factors survive a restart.
    pub flash: Option<PathBuf>,
    /// Where to write the truth file; default: next to the link or the PTY.
    pub truth: Option<PathBuf>,
}

/// Where a running virtual board can be reached.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SimBoardReady {
    /// Path of the pseudo-terminal the board serves.
    pub pty: String,
    /// The symbolic link pointing at `pty`, if one was asked for.
    pub link: Option<String>,
    /// Truth file (JSON lines, one per trial) the board appends to.
    pub truth_file: String,
    /// Name of the robot being simulated.
    pub robot: String,
    /// Seed of the simulation's random noise.
    pub seed: u64,
}

/// The truth file that goes with a port (the link path, or the PTY path).
pub fn truth_file_for(port: &Path) -> PathBuf {
    let mut s = port.as_os_str().to_owned();
    s.push(".truth.jsonl");
    PathBuf::from(s)
}

/// Whether an existing file's first bytes are a truth file (empty, or JSON lines of
/// [`TrialTruth`]): only such a file is emptied at start-up.
pub fn is_truth_file(head: &[u8]) -> bool {
    let Ok(text) = std::str::from_utf8(head) else {
        return false;
    };
    let mut lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    // The first MiB may cut the last line.
    if head.len() >= 1 << 20 {
        lines.pop();
    }
    lines
        .iter()
        .all(|l| serde_json::from_str::<TrialTruth>(l).is_ok())
}

/// Reads the true end errors recorded by a virtual board, in trial order.
pub fn read_truths(file: &Path) -> Result<Vec<TrialTruth>> {
    if !file.exists() {
        return Ok(Vec::new());
    }
    // One line of ~200 bytes per trial: 64 MiB is hundreds of thousands of trials.
    let text = crate::input::read_text(file, 64 << 20, "virtual board's truth file")?;
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            serde_json::from_str(l)
                .with_context(|| format!("{}:{}: not a truth record", file.display(), i + 1))
        })
        .collect()
}

/// Builds the simulated robot for the options.
pub fn build_sim(opts: &SimBoardOptions) -> Result<(calib_core::Robot, SimRobot)> {
    let robot = robot_file::load(&opts.robot)?;
    let effects = opts
        .effects
        .iter()
        .map(|e| Effect::parse(e).with_context(|| format!("--effect {e}")))
        .collect::<Result<Vec<_>>>()?;
    let (mut faults, surface) = sim::Faults::from_effects(&robot, &effects, Surface::flat())?;
    faults.travel_noise_m_per_sqrt_m = opts.roughness;
    let cfg = SimConfig {
        seed: opts.seed,
        turn_scrub: opts.turn_scrub,
        ..SimConfig::default()
    };
    let sim = SimRobot::new(&robot, faults, surface, cfg)?;
    Ok((robot, sim))
}

/// Runs the board until `stop` is set; `ready` is called once the PTY exists.
pub fn run(
    opts: &SimBoardOptions,
    stop: Arc<AtomicBool>,
    ready: impl FnOnce(&SimBoardReady),
) -> Result<()> {
    let (robot, sim) = build_sim(opts)?;
    let flash = board_flash(opts.flash.clone()).map_err(|e| anyhow::anyhow!("--flash: {e}"))?;
    if let Some(why) = flash.damaged() {
        eprintln!("warning: --flash {why}");
    }
    let mut board = VirtualBoard::boot(&robot, sim, flash)?;
    let (mut master, slave) =
        serialport::TTYPort::pair().context("cannot create a pseudo-terminal")?;
    use serialport::SerialPort;
    master.set_timeout(std::time::Duration::ZERO)?;
    let pty = slave.name().context("pseudo-terminal without a name")?;
    // This process keeps the terminal's other end open, so `wheelcal estop` finds it
    // among the port's holders and signals it: it answers that it holds no port.
    crate::stop::serve_relay_signal();
    let truth_file = opts
        .truth
        .clone()
        .unwrap_or_else(|| truth_file_for(opts.link.as_deref().unwrap_or(Path::new(&pty))));
    // Start each session with an empty truth file (trial numbers restart too), but never
    // empty a file that is not one; checked before the link is made, so a refusal
    // leaves nothing behind.
    let what = "virtual board's truth file";
    formats::safe_write::check_target(&truth_file, what, is_truth_file)?;
    if let Some(link) = &opts.link {
        claim_link(link, Path::new(&pty))?;
    }
    if let Err(e) = formats::safe_write::write_file(&truth_file, b"", what, is_truth_file) {
        if let Some(link) = &opts.link {
            release_link(link, Path::new(&pty));
        }
        return Err(e)
            .with_context(|| format!("cannot write the truth file {}", truth_file.display()));
    }
    ready(&SimBoardReady {
        pty: pty.clone(),
        link: opts.link.as_ref().map(|l| l.display().to_string()),
        truth_file: truth_file.display().to_string(),
        robot: robot.name.to_string(),
        seed: opts.seed,
    });
    let mut stream = PortStream { port: master };
    let tf = truth_file.clone();
    board.serve(
        &mut stream,
        opts.speed,
        || stop.load(Ordering::Relaxed),
        |t| {
            if let Ok(mut f) = std::fs::OpenOptions::new().append(true).open(&tf) {
                let _ = writeln!(f, "{}", serde_json::to_string(t).unwrap_or_default());
            }
        },
    );
    drop(slave);
    if let Some(link) = &opts.link {
        release_link(link, Path::new(&pty));
    }
    Ok(())
}

/// Points `link` at `pty`. Only a symbolic link may be replaced (a virtual board's link
/// left by an earlier session, which points at a pseudo-terminal or nowhere); a file, a
/// directory or any other link is never touched: `--link ~/notes.txt` must not delete
/// the notes.
pub fn claim_link(link: &Path, pty: &Path) -> Result<()> {
    match std::fs::symlink_metadata(link) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return Err(e).with_context(|| format!("cannot use --link {}", link.display())),
        Ok(m) if m.file_type().is_symlink() => {
            let target = std::fs::read_link(link).unwrap_or_default();
            // Only the stale link of a board that has gone: into /dev/pts, and the
            // pseudo-terminal gone with it. A live one may be another board's.
            let stale = target.starts_with("/dev/pts") && !target.exists();
            if !stale && !formats::safe_write::force() {
                let why = if target.starts_with("/dev/pts") {
                    "a pseudo-terminal that exists (another virtual board may be using it)"
                } else {
                    "not a virtual board's pseudo-terminal"
                };
                bail!(
                    "--link {} is a link to {}, {why}: not replaced (remove it, choose another path, or --force)",
                    link.display(),
                    target.display()
                );
            }
            std::fs::remove_file(link)
                .with_context(|| format!("cannot replace the old link {}", link.display()))?;
        }
        Ok(_) => bail!(
            "--link {} exists and is not a link: not replaced (remove it or choose another path)",
            link.display()
        ),
    }
    std::os::unix::fs::symlink(pty, link)
        .with_context(|| format!("cannot create the link {}", link.display()))
}

/// Removes `link` if it still points at `pty` (another board may have claimed it since).
pub fn release_link(link: &Path, pty: &Path) {
    if std::fs::read_link(link).is_ok_and(|t| t == pty) {
        let _ = std::fs::remove_file(link);
    }
}
