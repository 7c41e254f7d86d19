//! Physical plausibility of measured runs and of the factors computed from them: a runs
//! file typed in millimetres, a stray 1e300 or a first pass's `f_lon: -1` must be refused
//! with the reason, never turned into "recommended" factors the board would refuse.

use calib_core::correction;
use formats::runs_file::{RunRow, RunsError, RunsFile, TestKind};

/// Default longest path (UMBmark side or omni straight path) a runs file may name, m:
/// five times the largest square [Measuring errors] drives (10 m would already be a hall).
pub const DEFAULT_MAX_LENGTH_M: f64 = 50.0;

/// The largest end error a calibratable run can have: the straight path for omni (the
/// robot cannot end farther off than it drove), one side for UMBmark ([Measuring errors]'s robots end
/// 1-3 % of the side off; a whole side off needs factors far outside what a board
/// accepts, and is what millimetres typed into the metre columns look like), the radius
/// for a circle (an end a radius off has turned about a radian off its laps).
fn path_length_m(r: &RunRow) -> f64 {
    r.length_m
}

fn path_word(r: &RunRow) -> &'static str {
    match r.test {
        TestKind::Umbmark => "side of the square",
        TestKind::Omni => "path driven",
        TestKind::Circle => "radius of the circle",
    }
}

fn row_error(runs: &RunsFile, r: &RunRow, column: &str, message: String) -> RunsError {
    RunsError {
        path: runs.path.clone(),
        line: Some(r.line),
        column: Some(column.to_string()),
        message,
    }
}

const MM_HINT: &str = "looks like millimetres: the columns are metres";

/// Refuses rows outside physical bounds: a length over `max_length_m`, an end error
/// larger than the path driven. Says "looks like millimetres" when the value divided by
/// 1000 would fit.
pub fn check_runs(runs: &RunsFile, max_length_m: f64) -> Result<(), RunsError> {
    for r in &runs.rows {
        if r.length_m > max_length_m {
            let hint = if r.length_m / 1000.0 <= max_length_m {
                format!(" ({MM_HINT})")
            } else {
                String::new()
            };
            return Err(row_error(
                runs,
                r,
                "length_m",
                format!(
                    "{} m is over the {} m limit (--max-length){hint}",
                    sane(r.length_m),
                    sane(max_length_m)
                ),
            ));
        }
        let path = path_length_m(r);
        let err = r.x_err_m.hypot(r.y_err_m);
        if err > path {
            let hint = if err / 1000.0 <= 0.25 * path {
                format!(" ({MM_HINT})")
            } else {
                String::new()
            };
            // The radial error of both columns, not one of them.
            let mut e = row_error(
                runs,
                r,
                "",
                format!(
                    "radial end error {} m is larger than the {} m {} (sqrt(x_err_m^2 + y_err_m^2) of x_err_m {}, y_err_m {}){hint}",
                    sane(err),
                    sane(path),
                    path_word(r),
                    sane(r.x_err_m),
                    sane(r.y_err_m)
                ),
            );
            e.column = None;
            return Err(e);
        }
        if let Some(t) = r.theta_err_rad {
            if t.abs() > core::f64::consts::TAU {
                return Err(row_error(
                    runs,
                    r,
                    "theta_err_rad",
                    format!("{} rad is more than a full turn", sane(t)),
                ));
            }
        }
    }
    Ok(())
}

/// Refuses computed factors the board would refuse (finite, within [0.5, 2.0]), naming
/// the factor and what usually causes it.
pub fn check_factors(
    runs: &RunsFile,
    factors: &[(&'static str, Option<usize>, f64)],
) -> anyhow::Result<()> {
    for &(name, index, v) in factors {
        if let Err(e) = correction::check(name, index, v) {
            let typical = runs
                .rows
                .iter()
                .map(|r| r.x_err_m.hypot(r.y_err_m) / path_length_m(r))
                .fold(0.0f64, f64::max);
            let hint = if typical > 0.05 {
                format!(
                    "; end errors reach {:.0} % of the path: {MM_HINT}?",
                    typical * 100.0
                )
            } else {
                String::new()
            };
            anyhow::bail!(
                "{}: the computed {e}: the board would refuse it, so it is not recommended (check the runs{hint})",
                runs.path.display()
            );
        }
    }
    Ok(())
}

/// A number for a message: plain for the sizes one measures, scientific beyond.
pub fn sane(v: f64) -> String {
    if v == 0.0 || (1e-3..1e6).contains(&v.abs()) {
        let s = format!("{v:.6}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.3e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn runs(rows: &str) -> RunsFile {
        let text = format!("test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase\n{rows}");
        RunsFile::parse(&text, Path::new("r.csv")).unwrap()
    }

    #[test]
    fn millimetres_in_metre_columns_are_named() {
        // 32 mm typed as 32 on a 4 m square: 34 m off on a 4 m side, refused.
        let e = check_runs(&runs("umbmark,cw,4,32,-12,,\n"), 50.0).unwrap_err();
        let s = e.to_string();
        // The radial error of both columns is what is too large: named as such, with both
        // values (it named y_err_m alone when y was the larger).
        assert!(s.starts_with("r.csv:2: radial end error"), "{s}");
        assert!(s.contains("x_err_m 32, y_err_m -12"), "{s}");
        let s = check_runs(&runs("umbmark,cw,4,3,-16,,\n"), 50.0)
            .unwrap_err()
            .to_string();
        assert!(
            s.starts_with("r.csv:2: radial end error") && !s.contains("column '"),
            "{s}"
        );
        assert!(
            s.contains("larger than the 4 m side") && s.contains("millimetres"),
            "{s}"
        );
        // A length in millimetres.
        let s = check_runs(&runs("omni,4W-1,600,0.01,0,,\n"), 50.0)
            .unwrap_err()
            .to_string();
        assert!(
            s.contains("600 m is over the 50 m limit") && s.contains("millimetres"),
            "{s}"
        );
        // The limit is the caller's: 600 m passes a 1 km limit.
        assert!(check_runs(&runs("omni,4W-1,600,0.01,0,,\n"), 1000.0).is_ok());
        // 1e300: refused in a sane notation, no millimetre hint (1e297 m fits nothing).
        let s = check_runs(&runs("umbmark,ccw,4,1e300,0,,\n"), 50.0)
            .unwrap_err()
            .to_string();
        assert!(
            s.contains("1.000e300 m") && !s.contains("millimetres"),
            "{s}"
        );
        // Plausible rows pass: 30 mm on 4 m.
        assert!(check_runs(&runs("umbmark,cw,4,0.03,-0.012,,\n"), 50.0).is_ok());
    }

    #[test]
    fn refused_factors_are_not_recommended() {
        let r = runs("umbmark,cw,4,3,-1,,\n");
        let e = check_factors(&r, &[("c_l", None, 1.01), ("e_b", None, 3.25)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("e_b = 3.25 is outside [0.5, 2]"), "{e}");
        assert!(
            e.contains("not recommended") && e.contains("millimetres"),
            "{e}"
        );
        assert!(check_factors(&r, &[("f_lon", None, 1.02)]).is_ok());
        let e = check_factors(&r, &[("f_lat", Some(2), f64::NAN)]).unwrap_err();
        assert!(e.to_string().contains("f_lat[2] must be a finite number"));
    }

    #[test]
    fn sane_numbers() {
        assert_eq!(sane(16.0), "16");
        assert_eq!(sane(0.0325), "0.0325");
        assert_eq!(sane(1e300), "1.000e300");
        assert_eq!(sane(f64::INFINITY), "inf");
    }
}
