//! What the board says about itself: `info`'s report, the words for what boot found in
//! flash, and the one-line status `status`, `drive` and `run` print.

use crate::client::Client;
use anyhow::Result;
use calib_core::protocol::{Info, Mode, Status};
use serde::Serialize;
use std::fmt::Write as _;
use std::io::{Read, Write};

/// `wheelcal info`.
#[derive(Debug, Clone, Serialize)]
pub struct InfoReport {
    /// Firmware version text.
    pub firmware: String,
    /// The board's protocol version.
    pub protocol_version: u16,
    /// The board's schema fingerprint, 8 hex digits.
    pub schema: String,
    /// Name of the robot the board is configured for.
    pub robot: String,
    /// The robot's kind, as in the robot file.
    pub robot_kind: String,
    /// How the wheels are driven, lower case.
    pub drive: String,
    /// Wheels of the configured robot.
    pub wheel_count: u8,
    /// Wheel names, in the robot's wheel order.
    pub wheels: Vec<String>,
    /// Time since boot, s.
    pub uptime_s: f64,
    /// What boot found for the corrections ([`stored_word`]).
    pub corrections_at_boot: String,
    /// What boot found for the parameters ([`stored_word`]).
    pub params_at_boot: String,
    /// Trial-log RAM, bytes.
    pub log_capacity_bytes: u32,
    /// Bytes per log record for this robot.
    pub record_size_bytes: u16,
}

/// What boot found for one stored item, as a JSON word: `loaded`, `none_saved`,
/// `corrupted` (saved once, now unreadable: a lost calibration) or `flash_error`.
pub fn stored_word(s: calib_core::protocol::Stored) -> &'static str {
    use calib_core::protocol::Stored;
    match s {
        Stored::Loaded => "loaded",
        Stored::Missing => "none_saved",
        Stored::Invalid => "corrupted",
        Stored::StorageError => "flash_error",
    }
}

/// The words a user acts on: a corrupted item means a saved calibration was lost.
fn stored_human(word: &str) -> &str {
    match word {
        "loaded" => "loaded",
        "none_saved" => "none saved (nominal)",
        "corrupted" => "corrupted, using nominal",
        "flash_error" => "flash unreadable, using nominal",
        other => other,
    }
}

/// Asks the board for its info and parameters: what `wheelcal info` shows.
pub fn info<L: Read + Write>(c: &mut Client<L>) -> Result<InfoReport> {
    let i: Info = c.info()?;
    let p = c.params()?;
    Ok(InfoReport {
        firmware: i.firmware.to_string(),
        protocol_version: i.protocol_version,
        schema: format!("{:08x}", i.schema),
        robot: p.robot.name.to_string(),
        robot_kind: i.robot_kind.as_str().into(),
        drive: format!("{:?}", i.drive).to_lowercase(),
        wheel_count: i.wheel_count,
        wheels: p.robot.wheels.iter().map(|w| w.name.to_string()).collect(),
        uptime_s: i.uptime_ms as f64 / 1000.0,
        corrections_at_boot: stored_word(i.boot.corrections).into(),
        params_at_boot: stored_word(i.boot.params).into(),
        log_capacity_bytes: i.log_capacity,
        record_size_bytes: i.record_size,
    })
}

impl InfoReport {
    /// The report as text lines for a person.
    pub fn human(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "firmware      {} (protocol v{}, schema {})",
            self.firmware, self.protocol_version, self.schema
        );
        let _ = writeln!(
            s,
            "robot         {} ({}, {} drive), wheels: {}",
            self.robot,
            self.robot_kind,
            self.drive,
            self.wheels.join(", ")
        );
        let _ = writeln!(s, "uptime        {:.1} s", self.uptime_s);
        let _ = writeln!(
            s,
            "at boot       corrections {}, parameters {}",
            stored_human(&self.corrections_at_boot),
            stored_human(&self.params_at_boot)
        );
        let _ = writeln!(
            s,
            "trial log     {} KiB, {} bytes per record",
            self.log_capacity_bytes / 1024,
            self.record_size_bytes
        );
        s
    }
}

/// A one-line status.
pub fn status_line(s: &Status) -> String {
    let mode = match s.mode {
        Mode::Idle => "idle".to_string(),
        Mode::Drive => "drive".to_string(),
        Mode::Program { segment, segments } => {
            format!("program {}/{}", segment as u32 + 1, segments)
        }
    };
    let mut line = format!(
        "t {:>8.2} s  {:<12} pose ({:+.4} m, {:+.4} m, {:+.4} rad)  rates [{}]",
        s.uptime_ms as f64 / 1000.0,
        mode,
        s.pose.x,
        s.pose.y,
        s.pose.theta,
        s.wheel_rates
            .iter()
            .map(|r| format!("{r:+.2}"))
            .collect::<Vec<_>>()
            .join(" ")
    );
    if s.estop {
        line.push_str("  E-STOP");
    }
    if let Some(f) = s.fault {
        let _ = write!(line, "  FAULT ({f})");
    }
    if s.dropped_records > 0 {
        let _ = write!(line, "  log dropped {} records", s.dropped_records);
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::protocol::Stored;

    #[test]
    fn a_lost_calibration_is_named() {
        let w = stored_word(Stored::Invalid);
        assert_eq!(stored_human(w), "corrupted, using nominal");
        assert_eq!(
            stored_human(stored_word(Stored::Missing)),
            "none saved (nominal)"
        );
        assert_ne!(stored_word(Stored::Invalid), stored_word(Stored::Missing));
    }
}
