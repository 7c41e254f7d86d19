//! The page of `wheelcal calibrate --report DIR`: the factors and the exact `wheelcal
//! apply` command that puts them on a board first, then the fitted geometry, the
//! held-out errors, the laws kept and refused, the caveats, the plots (each with what to
//! see in it) and, folded, the text `calibrate` prints.
//!
//! Built from [`Calibration`]'s fields, never from its text. The command is checked the
//! way `apply` checks it: the report's `calibration.json` is read back as `apply` reads it
//! ([`SavedCalibration`]) and its factors for the robot fitted from must be ones the board
//! takes; otherwise the page says why there is no command.

use super::page::Page;
use crate::calibration::saved::SavedCalibration;
use anyhow::Result;
use calib_core::robot::Robot;
use calibrate::plots::ReportFigure;
use calibrate::{Calibration, Factors};
use std::path::{Path, PathBuf};

fn mm(v: f64) -> String {
    format!("{:.2} mm", v * 1e3)
}

fn before_after(b: f64, a: f64) -> String {
    format!("{} → {}", mm(b), mm(a))
}

/// The command that applies the report's calibration to a board holding the robot it was
/// fitted from and saves it: `wheelcal apply DIR/calibration.json --save` (the path as
/// given, shell-quoted).
pub fn apply_command(dir: &Path) -> String {
    let json = dir.join("calibration.json");
    format!(
        "wheelcal apply {} --save",
        shell_words::quote(&json.display().to_string())
    )
}

/// The factors as (name, value) rows: the board's (with the laws it applies) for a
/// differential drive, f_lat per wheel, f_lon and the turn law for wheels.
pub fn factor_rows(cal: &Calibration, robot: &Robot) -> Vec<Vec<String>> {
    let row = |n: &str, v: f64, what: &str| vec![n.to_string(), format!("{v:.6}"), what.into()];
    match &cal.factors {
        Factors::Diff {
            c_l,
            c_r,
            e_b,
            board,
        } => {
            let (c_l, c_r, e_b, laws) = match board {
                Some(b) => (b.c_l, b.c_r, b.e_b, Some(b.laws)),
                None => (*c_l, *c_r, *e_b, None),
            };
            let mut rows = vec![
                row("c_L", c_l, "left wheel's effective radius / nominal"),
                row("c_R", c_r, "right wheel's effective radius / nominal"),
                row("E_b", e_b, "effective wheelbase / nominal"),
            ];
            if let Some(l) = laws {
                for (n, v, what) in [
                    (
                        "e_b_arc",
                        l.e_b_arc,
                        "turn law: separation wider on arcs than in a turn in place",
                    ),
                    (
                        "speed_rel",
                        l.speed_rel,
                        "speed law: wheel size growth per m/s",
                    ),
                    (
                        "accel_slip_s",
                        l.accel_slip_s,
                        "acceleration law: ground lag, s",
                    ),
                ] {
                    if v != 0.0 {
                        rows.push(row(n, v, what));
                    }
                }
            }
            rows
        }
        Factors::Wheels {
            f_lat,
            f_lon,
            l_arc,
        } => {
            let mut rows: Vec<Vec<String>> = f_lat
                .iter()
                .enumerate()
                .map(|(i, v)| {
                    let name = robot
                        .wheels
                        .get(i)
                        .map_or(format!("wheel {}", i + 1), |w| w.name.to_string());
                    row(
                        &format!("f_lat {name}"),
                        *v,
                        "command multiplier (1 / radius scale)",
                    )
                })
                .collect();
            rows.push(row("f_lon", *f_lon, "common multiplier"));
            if *l_arc != 0.0 {
                rows.push(row(
                    "l_arc",
                    *l_arc,
                    "turn law: wheel distance longer on arcs",
                ));
            }
            rows
        }
    }
}

/// The answer in one paragraph: the factors, and how much better the fitted geometry
/// dead-reckons recordings it did not see (the cross-validation mean, else the held-out
/// recording), or the fit's own figure when nothing was held out.
pub fn headline(cal: &Calibration, robot: &Robot) -> String {
    let factors = factor_rows(cal, robot)
        .iter()
        .map(|r| format!("{} {}", r[0], r[1]))
        .collect::<Vec<_>>()
        .join(", ");
    let evidence = if let Some(m) = cal.leave_one_out.means() {
        format!(
            "on recordings left out of the fit, dead reckoning goes from {} to {} RMS (mean over {}, left out by {}).",
            mm(m.before_m),
            mm(m.after_m),
            cal.leave_one_out.0.len(),
            cal.cv_by.unwrap_or("run")
        )
    } else if let Some(h) = &cal.heldout {
        format!(
            "on the held-out recording {}, dead reckoning goes from {} to {} RMS.",
            h.name,
            mm(h.rmse_before_m),
            mm(h.rmse_after_m)
        )
    } else {
        format!(
            "nothing was held out; on the recordings fitted the error goes from {} to {} RMS.",
            mm(cal.joint_rmse_before_m),
            mm(cal.joint_rmse_after_m)
        )
    };
    format!("Factors: {factors}; {evidence}")
}

/// Writes `index.html` into `dir`, beside the report's `calibration.json` (already
/// written: the apply command is checked against it) and the `figures`; `summary` is the
/// text `calibrate` prints, folded at the end. Returns the page's path.
pub fn write(
    cal: &Calibration,
    robot: &Robot,
    figures: &[ReportFigure],
    summary: &str,
    dir: &Path,
) -> Result<PathBuf> {
    let mut page = Page::new(&format!("wheelcal calibrate: {}", cal.robot));
    page.answer(&headline(cal, robot));
    page.heading("Factors to apply");
    page.table(&["factor", "value", "what it is"], &factor_rows(cal, robot));
    let json = dir.join("calibration.json");
    let checked = SavedCalibration::read(&json, robot, "apply").and_then(|s| {
        let c = s.factors_for(robot)?;
        c.validate(robot)
            .map_err(|e| anyhow::anyhow!("the board would refuse them: {e}"))?;
        let carried = s.board_geometry(robot)?.is_some();
        Ok((s.without_factor(), carried))
    });
    match checked {
        Ok((lost, carried)) => {
            page.paragraph(&format!(
                "On a board holding robot '{}' (the geometry fitted from), this sets the factors and saves them:",
                robot.name
            ));
            page.command(&apply_command(dir));
            if carried {
                page.paragraph(&format!(
                    "No firmware factor carries {}: apply puts the calibration's fitted geometry on the board (its board_geometry, with factors of one and the laws) and saves it too.",
                    lost.join(", ")
                ));
            } else if !lost.is_empty() {
                page.paragraph(&format!(
                    "No firmware factor carries {}: for those, give the board the fitted geometry (calibrate --write-board-robot, then apply --board-robot).",
                    lost.join(", ")
                ));
            }
        }
        Err(e) => page.paragraph(&format!("No apply command: {e:#}")),
    }
    page.paragraph(&format!(
        "{} recording(s) fitted ({}); minimised: {}.",
        cal.recordings.len(),
        cal.recordings.join(", "),
        cal.objective
    ));
    page.heading("Fitted geometry");
    let rows: Vec<Vec<String>> = cal
        .params
        .iter()
        .map(|p| {
            vec![
                p.spec.name.clone(),
                if p.sigma_exceeds_range() {
                    format!("{:.5} (not fixed by the data)", p.value)
                } else {
                    format!("{:.5} ± {:.5}", p.value, p.sigma)
                },
                format!("{}", p.spec.nominal),
                format!("{:.4} .. {:.4}", p.spec.plausible.0, p.spec.plausible.1),
            ]
        })
        .collect();
    page.table(
        &["parameter", "fitted ± one sigma", "nominal", "plausible"],
        &rows,
    );
    page.heading("Held out: recordings the fit did not see");
    let mut rows: Vec<Vec<String>> = cal
        .leave_one_out
        .0
        .iter()
        .map(|h| {
            vec![
                h.name.clone(),
                before_after(h.rmse_before_m, h.rmse_after_m),
                before_after(h.aligned_before_m, h.aligned_after_m),
            ]
        })
        .collect();
    if let Some(m) = cal.leave_one_out.means() {
        rows.push(vec![
            "mean".into(),
            before_after(m.before_m, m.after_m),
            before_after(m.aligned_before_m, m.aligned_after_m),
        ]);
    }
    if let Some(h) = &cal.heldout {
        rows.push(vec![
            format!("{} (--holdout)", h.name),
            before_after(h.rmse_before_m, h.rmse_after_m),
            before_after(h.aligned_before_m, h.aligned_after_m),
        ]);
    }
    if rows.is_empty() {
        page.paragraph("None: no cross-validation and no --holdout recording.");
    } else {
        page.table(
            &[
                "recording",
                "dead reckoning from its first pose, nominal → fitted",
                "start pose and clocks fitted, nominal → fitted",
            ],
            &rows,
        );
    }
    page.heading("Laws kept and refused");
    if cal.law_tests.is_empty() {
        page.paragraph("No law was tested on these recordings (the notes say why).");
    } else {
        let rows: Vec<Vec<String>> = cal
            .law_tests
            .iter()
            .map(|l| {
                vec![
                    format!("{} ({})", l.law, l.parameter),
                    format!("{:+.4} ± {:.4}", l.value, l.sigma),
                    format!(
                        "{} with, {} without ({} folds)",
                        mm(l.heldout_m),
                        mm(l.constant_heldout_m),
                        l.folds
                    ),
                    if l.kept { "kept" } else { "refused" }.to_string(),
                ]
            })
            .collect();
        page.table(
            &["law", "value ± one sigma", "held-out error", "decision"],
            &rows,
        );
    }
    let laws: Vec<String> = cal
        .notes
        .iter()
        .filter(|n| n.contains(" law"))
        .cloned()
        .collect();
    page.list(&laws);
    let mut caveats: Vec<String> = cal
        .inseparable
        .0
        .iter()
        .map(|i| {
            format!(
                "not separable: {} and {} (correlation {:+.3}); to separate them: {}",
                i.params[0], i.params[1], i.correlation, i.advice
            )
        })
        .collect();
    caveats.extend(cal.implausible.iter().map(|i| {
        format!(
            "implausible: {} = {:.5} outside {:.4}..{:.4}; most likely stands in for {}",
            i.name, i.value, i.plausible.0, i.plausible.1, i.stands_for
        )
    }));
    caveats.extend(
        cal.notes
            .iter()
            .filter(|n| !n.contains(" law"))
            .map(|n| format!("note: {n}")),
    );
    if !caveats.is_empty() {
        page.heading("Caveats");
        page.list(&caveats);
    }
    page.heading("Plots");
    for f in figures {
        page.image(&f.file, &f.title, &f.what_to_see);
    }
    page.folded_text("Full text output (as calibrate prints it)", summary);
    page.write(dir)
}
