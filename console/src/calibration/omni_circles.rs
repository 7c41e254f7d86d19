//! The omni circle test in `omni compute`: circle rows beside the straight paths give the
//! robot's turn in place (its wheels' distance from the centre, which straight paths never
//! show) and its turn law, without motion capture ([`calib_core::omni_circle_test`]).
//!
//! The circles are measured with the factors the straight paths were measured with (the
//! `--previous` pass's, else none). The new factors change every wheel's travel, so the
//! odometry's turn in place changes by their mean radius scale; the wheel distance the
//! board is given accounts for that: L x (m_new / m_old) / G_0.

use anyhow::{anyhow, Result};
use calib_core::correction::E_B_ARC_MAX;
use calib_core::omni_circle_test::{self, OmniRadius};
use calib_core::robot::Robot;
use calib_core::Corrections;
use formats::runs_file::{Phase, RunsFile};
use serde::Serialize;
use std::fmt::Write as _;

/// What the circles of a runs file show for an omni robot.
#[derive(Debug, Clone, Serialize)]
pub struct OmniCircleReport {
    /// The robot's turn in place over its odometry's, with the factors in force while the
    /// circles were measured.
    pub spin_gain: f64,
    /// Its standard error.
    pub spin_gain_sigma: f64,
    /// The board's wheel distances times this (with the new factors in force) make its
    /// odometry turn in place as the robot does.
    pub wheel_distance_scale: f64,
    /// Its standard error.
    pub wheel_distance_scale_sigma: f64,
    /// The turn law: the wheels' distance on arcs is 1 + l_arc (1 - rho^2) times that of
    /// a turn in place.
    pub l_arc: f64,
    /// Its standard error.
    pub l_arc_sigma: f64,
    /// Whether the law is kept: significant at 3 sigma and within what a board accepts.
    pub kept: bool,
    /// Per radius: runs, heading gains, the law's share.
    pub radii: Vec<OmniRadius>,
    /// Circle rows measured `after`, with the board robot and the law in force: what is
    /// left, which should be a turn in place of 1 and a law of 0 within their sigmas.
    pub after: Option<OmniResidual>,
    /// The sentence the summary prints about the law.
    pub verdict: String,
}

/// What the `after` circles still show, relative to the board robot and law in force.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct OmniResidual {
    /// The robot's turn in place over its odometry's.
    pub spin_gain: f64,
    /// Its standard error.
    pub spin_gain_sigma: f64,
    /// The law left over.
    pub l_arc: f64,
    /// Its standard error.
    pub l_arc_sigma: f64,
}

/// The mean of `c`'s wheel radius scales on `robot`: how much further the odometry counts
/// a turn in place with `c` in force than without (every wheel turns alike in place).
fn mean_radius_scale(c: &Corrections, robot: &Robot) -> f64 {
    let n = robot.wheels.len();
    (0..n).map(|i| c.radius_scale(robot, i)).sum::<f64>() / n as f64
}

/// The omni circle test of `runs` (None without circle rows) for `robot` (the board's
/// robot file), the circles measured with `measured_with` in force and the board to hold
/// `new` afterwards. Errors name the file.
pub fn compute(
    robot: &Robot,
    runs: &RunsFile,
    measured_with: &Corrections,
    new: &Corrections,
) -> Result<Option<OmniCircleReport>> {
    let before = runs.circles(Phase::Before);
    if before.is_empty() {
        if !runs.circles(Phase::After).is_empty() {
            anyhow::bail!(
                "{}: circle rows measured after but none before: the omni circle test reads circles measured with the straight paths' factors (phase before)",
                runs.path.display()
            );
        }
        return Ok(None);
    }
    let named = |e: calib_core::circle_test::CircleError| anyhow!("{}: {e}", runs.path.display());
    let l = robot.mean_wheel_distance_m();
    let law = omni_circle_test::omni_turn_law(&before, l).map_err(named)?;
    let ratio = mean_radius_scale(new, robot) / mean_radius_scale(measured_with, robot);
    let scale = ratio / law.spin_gain;
    let scale_sigma = scale * law.spin_gain_sigma / law.spin_gain;
    let after = runs.circles(Phase::After);
    let after = if after.is_empty() {
        None
    } else {
        // Measured on the board robot: its wheels at L times the scale.
        let a = omni_circle_test::omni_turn_law(&after, l * scale).map_err(named)?;
        Some(OmniResidual {
            spin_gain: a.spin_gain,
            spin_gain_sigma: a.spin_gain_sigma,
            l_arc: a.l_arc,
            l_arc_sigma: a.sigma,
        })
    };
    let kept = law.significant();
    let (k, s) = (law.l_arc, law.sigma);
    let verdict = if kept {
        format!(
            "turn law kept: l_arc {k:+.5} ± {s:.5}: the wheels' distance from the centre is {:.2} % {} on arcs than in a turn in place (roller and tyre scrub)",
            k.abs() * 100.0,
            if k > 0.0 { "longer" } else { "shorter" }
        )
    } else if k.abs() > E_B_ARC_MAX {
        format!(
            "no turn law: l_arc {k:+.5} ± {s:.5} is beyond the ±{E_B_ARC_MAX} scrub can explain (and a board accepts): check the circle rows (metres, radians, measured minus odometry, the direction driven)"
        )
    } else {
        format!(
            "no turn law: l_arc {k:+.5} ± {s:.5} is within 3 sigma of 0: the circles turn as the turn in place says"
        )
    };
    Ok(Some(OmniCircleReport {
        spin_gain: law.spin_gain,
        spin_gain_sigma: law.spin_gain_sigma,
        wheel_distance_scale: scale,
        wheel_distance_scale_sigma: scale_sigma,
        l_arc: k,
        l_arc_sigma: s,
        kept,
        radii: law.radii.to_vec(),
        after,
        verdict,
    }))
}

impl OmniCircleReport {
    /// `robot` with its wheels' distances from the centre scaled to the turn in place:
    /// the geometry the board takes (`robot set`) beside the new factors.
    pub fn board_robot(&self, robot: &Robot) -> Robot {
        let mut out = robot.clone();
        for w in out.wheels.iter_mut() {
            w.l_m *= self.wheel_distance_scale;
        }
        out
    }

    /// The law the board applies (0 when not kept).
    pub fn l_arc_kept(&self) -> f64 {
        if self.kept {
            self.l_arc
        } else {
            0.0
        }
    }

    /// The summary's lines.
    pub fn human(&self) -> String {
        let mut s = String::from(
            "\nOmni circle test (the turn in place and the turn law straight paths cannot show):\n",
        );
        for r in &self.radii {
            let _ = writeln!(
                s,
                "  radius {:.3} m: {} cw, {} ccw runs; heading gain cw {:.5}, ccw {:.5}, mean {:.5} ± {:.5}; law's share {:.2}{}",
                r.radius_m,
                r.runs_cw,
                r.runs_ccw,
                r.gain_cw,
                r.gain_ccw,
                r.gain,
                r.gain_sigma,
                r.share,
                if r.share == 0.0 { " (a turn in place)" } else { "" }
            );
        }
        let _ = writeln!(
            s,
            "  in place the robot turns {:.5} ± {:.5} times what its odometry says: with the new factors, the board's wheel distances times {:.5} ± {:.5}",
            self.spin_gain, self.spin_gain_sigma, self.wheel_distance_scale, self.wheel_distance_scale_sigma
        );
        let _ = writeln!(s, "  {}", self.verdict);
        if let Some(a) = &self.after {
            let _ = writeln!(
                s,
                "  after: with the board robot and the law in force, the robot turns {:.5} ± {:.5} times its odometry in place and leaves l_arc {:+.5} ± {:.5}",
                a.spin_gain, a.spin_gain_sigma, a.l_arc, a.l_arc_sigma
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::geometry::tests::robot;
    use calib_core::motion::Direction;
    use calib_core::omni_circle_test::OmniCircleModel;
    use std::path::Path;

    /// Circle rows of an omni3 whose wheels sit 3 % further out than its file says and
    /// whose arcs follow a 2 % law, measured with no factors in force: two turns in place
    /// (1 cm, heading measured) and two 0.5 m circles each way, 2 laps.
    fn runs_file(wheels_smaller: f64) -> RunsFile {
        let model = OmniCircleModel {
            wheel_distance_m: 0.15,
            spin_gain: wheels_smaller / 1.03,
            l_arc: 0.02,
        };
        let mut text =
            String::from("test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase,laps\n");
        for r in [0.01, 0.5] {
            for dir in [Direction::Cw, Direction::Ccw] {
                let run = model.run(dir, r, 2);
                for _ in 0..2 {
                    let th = if r < 0.1 {
                        format!("{}", run.theta_err_rad.unwrap())
                    } else {
                        String::new()
                    };
                    text.push_str(&format!(
                        "circle,{},{r},{},{},{th},,2\n",
                        dir.as_str(),
                        run.x_err_m,
                        run.y_err_m
                    ));
                }
            }
        }
        RunsFile::parse(&text, Path::new("runs.csv")).unwrap()
    }

    /// The wheel distance comes back as 1.03 times the file's and the law as 0.02 (to
    /// the runs file's printed precision); with wheels 2 % small, which the straight
    /// paths' new factors correct (their radius scales 0.98), the turn in place the
    /// circles show is 0.98 / 1.03 but the distance is still 1.03: the new factors take
    /// their share.
    #[test]
    fn circles_give_the_wheel_distance_and_the_law_with_the_new_factors() {
        let robot = robot("omni3");
        let none = Corrections::None;
        let rep = compute(&robot, &runs_file(1.0), &none, &none)
            .unwrap()
            .unwrap();
        assert!((rep.wheel_distance_scale - 1.03).abs() < 1e-9, "{rep:?}");
        assert!((rep.l_arc - 0.02).abs() < 1e-9, "{rep:?}");
        assert!(rep.kept, "{rep:?}");
        let b = rep.board_robot(&robot);
        assert!((b.mean_wheel_distance_m() - 0.15 * 1.03).abs() < 1e-12);
        let f = 1.0 / 0.98;
        let new = Corrections::omni([f; 3].into_iter().collect(), 1.0, 0.0);
        let rep = compute(&robot, &runs_file(0.98), &none, &new)
            .unwrap()
            .unwrap();
        assert!((rep.spin_gain - 0.98 / 1.03).abs() < 1e-9, "{rep:?}");
        assert!((rep.wheel_distance_scale - 1.03).abs() < 1e-9, "{rep:?}");
        assert!((rep.l_arc - 0.02).abs() < 1e-9, "{rep:?}");
    }
}
