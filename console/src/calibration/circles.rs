//! The circle test in `umbmark compute`: circle rows beside the squares give the turn law
//! ([`calib_core::circle_test`]), which squares alone cannot show, without motion
//! capture.

use anyhow::Result;
use calib_core::circle_test::{self, RadiusLaw};
use calib_core::correction::{DiffLaws, E_B_ARC_MAX};
use calibrate::BoardFactors;
use formats::runs_file::{Phase, RunsFile};
use serde::Serialize;
use std::fmt::Write as _;

/// What the circles of a runs file show, beside the squares' factors.
#[derive(Debug, Clone, Serialize)]
pub struct CircleReport {
    /// The turn law: the effective wheelbase on arcs is 1 + e_b_arc times the squares'
    /// (in a turn in place).
    pub e_b_arc: f64,
    /// Its standard error, the runs' spread and the squares' E_b together.
    pub e_b_arc_sigma: f64,
    /// The squares' E_b standard error counted in it.
    pub e_b_sigma: f64,
    /// Whether the law is kept: significant at 3 sigma and within what a board accepts.
    pub kept: bool,
    /// Per radius: runs, heading gains, the law's share and its value there, and the
    /// diameter ratio the circles show (a check on the squares' E_d).
    pub radii: Vec<RadiusLaw>,
    /// With two radii or more: the largest distance of one radius's law from the
    /// combined one, in its sigmas (over 3: the law's shape 1 - rho^2 does not hold).
    pub shape_misfit_sigma: Option<f64>,
    /// Circle rows measured `after`, with the factors (and law) in force: the law left
    /// over, which should be within its sigma of 0.
    pub after: Option<ResidualLaw>,
    /// The sentence the summary prints about the law.
    pub verdict: String,
}

/// The law the `after` circles still show, relative to the factors in force.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ResidualLaw {
    /// Left-over e_b_arc.
    pub e_b_arc: f64,
    /// Its standard error from the runs' spread.
    pub e_b_arc_sigma: f64,
}

/// The circle test of `runs` (None without circle rows), the squares' exact fit having
/// given `e_b` from `cw_x` and `ccw_x` (their end errors along x) on a square of
/// `side_m`, for a robot of nominal separation `separation_m`. Errors name the file.
pub fn compute(
    runs: &RunsFile,
    (cw_x, ccw_x): (&[f64], &[f64]),
    side_m: f64,
    e_b: f64,
    separation_m: f64,
) -> Result<Option<CircleReport>> {
    let before = runs.circles(Phase::Before);
    if before.is_empty() {
        if !runs.circles(Phase::After).is_empty() {
            anyhow::bail!(
                "{}: circle rows measured after but none before: the law is computed from circles measured with the squares' factors (phase before)",
                runs.path.display()
            );
        }
        return Ok(None);
    }
    let named = |e: circle_test::CircleError| anyhow::anyhow!("{}: {e}", runs.path.display());
    let e_b_sigma = circle_test::umbmark_e_b_sigma(cw_x, ccw_x, side_m, e_b).unwrap_or(0.0);
    let law = circle_test::turn_law(&before, e_b, e_b_sigma, separation_m).map_err(named)?;
    let after = runs.circles(Phase::After);
    let after = if after.is_empty() {
        None
    } else {
        // With the squares' factors in force, odometry's separation is E_b b.
        let l = circle_test::turn_law(&after, 1.0, 0.0, e_b * separation_m).map_err(named)?;
        Some(ResidualLaw {
            e_b_arc: l.e_b_arc,
            e_b_arc_sigma: l.sigma,
        })
    };
    let kept = law.significant();
    let (k, s) = (law.e_b_arc, law.sigma);
    let verdict = if kept {
        format!(
            "turn law kept: e_b_arc {k:+.5} ± {s:.5}: the effective wheelbase is {:.2} % {} on arcs than in a turn in place (tyre scrub)",
            k.abs() * 100.0,
            if k > 0.0 { "wider" } else { "narrower" }
        )
    } else if k.abs() > E_B_ARC_MAX {
        format!(
            "no turn law: e_b_arc {k:+.5} ± {s:.5} is beyond the ±{E_B_ARC_MAX} a tyre can explain (and a board accepts): check the circle rows (metres, measured minus odometry, the direction driven)"
        )
    } else {
        format!(
            "no turn law: e_b_arc {k:+.5} ± {s:.5} is within 3 sigma of 0: the circles turn as the squares' E_b says"
        )
    };
    Ok(Some(CircleReport {
        e_b_arc: k,
        e_b_arc_sigma: s,
        e_b_sigma,
        kept,
        shape_misfit_sigma: law.shape_misfit(),
        radii: law.radii.to_vec(),
        after,
        verdict,
    }))
}

impl CircleReport {
    /// The board's factors with the law, when it is kept.
    pub fn board(&self, c_l: f64, c_r: f64, e_b: f64) -> Option<BoardFactors> {
        self.kept.then(|| BoardFactors {
            c_l,
            c_r,
            e_b,
            laws: DiffLaws {
                e_b_arc: self.e_b_arc,
                ..DiffLaws::default()
            },
            // The circle test measures turns in place and arcs by hand, no range.
            range: Default::default(),
        })
    }

    /// The summary's lines, `e_d` the squares' for comparison.
    pub fn human(&self, e_d: f64, board: Option<&BoardFactors>) -> String {
        let mut s = String::from("\nCircle test (the turn law squares cannot show):\n");
        for r in &self.radii {
            let _ = writeln!(
                s,
                "  radius {:.3} m: {} cw, {} ccw runs; heading gain cw {:.5}, ccw {:.5}; law's share {:.2}; e_b_arc {:+.5} ± {:.5}; E_d {:.5} (squares {:.5})",
                r.radius_m, r.runs_cw, r.runs_ccw, r.gain_cw, r.gain_ccw, r.share, r.e_b_arc, r.sigma, r.e_d, e_d
            );
        }
        let _ = writeln!(
            s,
            "  {} (sigma counts the squares' E_b, ± {:.5})",
            self.verdict, self.e_b_sigma
        );
        match self.shape_misfit_sigma {
            Some(m) if m <= 3.0 => {
                let _ = writeln!(
                    s,
                    "  the radii agree with the law's shape 1 - rho^2 (largest departure {m:.1} sigma)"
                );
            }
            Some(m) => {
                let _ = writeln!(
                    s,
                    "  the radii disagree ({m:.1} sigma): this robot's scrub does not follow 1 - rho^2; the law above is their weighted mean"
                );
            }
            None => {}
        }
        if let Some(a) = &self.after {
            let _ = writeln!(
                s,
                "  after: the circles measured with the factors in force leave e_b_arc {:+.5} ± {:.5}",
                a.e_b_arc, a.e_b_arc_sigma
            );
        }
        if let Some(b) = board {
            let _ = writeln!(s, "  the board takes: wheelcal {}", b.command());
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use crate::calibration::umbmark;
    use calib_core::circle_test::CircleModel;
    use calib_core::motion::Direction;
    use calib_core::robot::presets;
    use formats::runs_file::RunsFile;
    use std::path::Path;

    /// A runs file of MoboLab (b = 0.4 m) with E_d 1.004 and E_b 1.02: three 4 m squares
    /// each way, and three 0.5 m circles of 2 laps each way for a turn law `k`, the x
    /// errors scattered by +-`noise` (m), circles as calib-core's `CircleModel` drives them.
    fn runs_file(k: f64, noise: f64, after: &str) -> RunsFile {
        let (ed, eb, b, r) = (1.004, 1.02, 0.4, 0.5);
        let mut text =
            String::from("test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase,laps\n");
        let scatter = |i: usize| [noise, -noise, 0.0][i % 3];
        let model = CircleModel {
            separation_m: b,
            e_b: eb,
            e_b_arc: k,
            e_d: ed,
        };
        for dir in [Direction::Cw, Direction::Ccw] {
            let name = dir.as_str();
            let (x, y, _) = calib_core::umbmark::square_end_error(ed, eb, 4.0, b, dir).unwrap();
            for i in 0..3 {
                text.push_str(&format!("umbmark,{name},4,{},{y},,,\n", x + scatter(i)));
            }
            let end = model.run(dir, r, 2);
            for i in 0..3 {
                text.push_str(&format!(
                    "circle,{name},{r},{},{},,,2\n",
                    end.x_err_m + scatter(i + 1),
                    end.y_err_m
                ));
            }
        }
        text.push_str(after);
        RunsFile::parse(&text, Path::new("runs.csv")).unwrap()
    }

    #[test]
    fn circles_beside_the_squares_give_the_turn_law_and_the_board_its_command() {
        // 2 mm of scatter: three runs at +-2 mm and 0 spread by 2 mm, a standard error of
        // 1.15 mm on x = R 2 pi N (G - 1): 1.8e-4 of gain a direction, 1.3e-4 for their
        // mean, 1.5e-4 on the law at the 0.84 share (the squares' E_b adds a little). The
        // law must come back within 4 sigma, sigma within a factor 1.5 of that.
        let rep = umbmark::compute(&presets::mobolab(), &runs_file(0.03, 0.002, "")).unwrap();
        let c = rep.circles.as_ref().expect("circle rows");
        assert!((c.e_b_arc - 0.03).abs() < 4.0 * c.e_b_arc_sigma, "{c:?}");
        assert!(c.e_b_arc_sigma > 1e-4 && c.e_b_arc_sigma < 3e-4, "{c:?}");
        assert!(c.kept && c.verdict.contains("3.00 % wider"), "{c:?}");
        assert!((c.radii[0].e_d - 1.004).abs() < 5e-4, "{c:?}");
        let board = &rep.factors.as_ref().expect("board factors").board;
        assert_eq!((board.e_b, board.laws.e_b_arc), (rep.eb, c.e_b_arc));
        let text = rep.human();
        assert!(text.contains("--e-b-arc"), "{text}");
        // The JSON carries factors.board, which `factors export --ros2 --from` reads.
        let json = serde_json::to_value(&rep).unwrap();
        assert_eq!(
            json["factors"]["board"]["e_b_arc"].as_f64(),
            Some(c.e_b_arc)
        );
        assert!(json["circles"]["radii"][0]["share"].is_f64());
    }

    #[test]
    fn no_law_is_kept_where_there_is_none() {
        // The control: the same robot without a law, 5 mm of scatter.
        let rep = umbmark::compute(&presets::mobolab(), &runs_file(0.0, 0.005, "")).unwrap();
        let c = rep.circles.as_ref().unwrap();
        assert!(!c.kept && c.verdict.starts_with("no turn law"), "{c:?}");
        assert!(rep.factors.is_none());
        assert!(!rep.human().contains("--e-b-arc"));
        // Circles measured after with the factors in force, ending +-0.1 mm from where
        // odometry says: nothing is left (to 1e-6; their own sigma is about 3e-5).
        let after = "circle,cw,0.5,0.0001,0,,after,1\ncircle,cw,0.5,-0.0001,0,,after,1\n\
                     circle,ccw,0.5,0.0001,0,,after,1\ncircle,ccw,0.5,-0.0001,0,,after,1\n";
        let rep = umbmark::compute(&presets::mobolab(), &runs_file(0.0, 0.005, after)).unwrap();
        let a = rep.circles.unwrap().after.unwrap();
        assert!(a.e_b_arc.abs() < 1e-6 && a.e_b_arc_sigma < 1e-4, "{a:?}");
    }

    #[test]
    fn bad_circle_rows_are_refused_naming_the_file() {
        // One circle a direction; circles after but none before.
        let text = "test,path,length_m,x_err_m,y_err_m,laps\n\
            umbmark,cw,4,0.01,0.02,\numbmark,cw,4,0.012,0.018,\n\
            umbmark,ccw,4,-0.03,0.01,\numbmark,ccw,4,-0.028,0.012,\n\
            circle,cw,0.5,-0.03,0,2\ncircle,ccw,0.5,-0.03,0,2\ncircle,ccw,0.5,-0.02,0,2\n";
        let runs = RunsFile::parse(text, Path::new("r.csv")).unwrap();
        let e = umbmark::compute(&presets::mobolab(), &runs)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("r.csv: the circles of radius 0.5 m have 1 cw run"),
            "{e}"
        );
        let text = "test,path,length_m,x_err_m,y_err_m,phase\n\
            umbmark,cw,4,0.01,0.02,\numbmark,cw,4,0.012,0.018,\n\
            umbmark,ccw,4,-0.03,0.01,\numbmark,ccw,4,-0.028,0.012,\n\
            circle,cw,0.5,-0.03,0,after\ncircle,ccw,0.5,-0.03,0,after\n";
        let runs = RunsFile::parse(text, Path::new("r.csv")).unwrap();
        let e = umbmark::compute(&presets::mobolab(), &runs)
            .unwrap_err()
            .to_string();
        assert!(e.contains("measured after but none before"), "{e}");
        // A circle tighter than half the wheelbase (0.2 m on MoboLab).
        let text = "test,path,length_m,x_err_m,y_err_m\n\
            umbmark,cw,4,0.01,0.02\numbmark,cw,4,0.012,0.018\n\
            umbmark,ccw,4,-0.03,0.01\numbmark,ccw,4,-0.028,0.012\n\
            circle,cw,0.15,0,0\ncircle,cw,0.15,0,0\ncircle,ccw,0.15,0,0\ncircle,ccw,0.15,0,0\n";
        let runs = RunsFile::parse(text, Path::new("r.csv")).unwrap();
        let e = umbmark::compute(&presets::mobolab(), &runs)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not wider than half the wheelbase"), "{e}");
        // Circles without squares: nothing to measure them against.
        let text = "test,path,length_m,x_err_m,y_err_m\n\
            circle,cw,0.5,0,0\ncircle,cw,0.5,0,0\ncircle,ccw,0.5,0,0\ncircle,ccw,0.5,0,0\n";
        let runs = RunsFile::parse(text, Path::new("r.csv")).unwrap();
        let e = umbmark::compute(&presets::mobolab(), &runs)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("r.csv: no UMBmark 'before' runs") && e.contains("squares' E_b"),
            "{e}"
        );
    }
}
