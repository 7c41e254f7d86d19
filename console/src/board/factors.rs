//! The board's correction factors as people read and give them: the JSON/text view,
//! `factors set`'s merge with the board's current factors, the factors in words.

use anyhow::{bail, Result};
use calib_core::correction::{DiffLaws, LawRange};
use calib_core::robot::MAX_WHEELS;
use calib_core::Corrections;
use serde::Serialize;

/// Corrections in the JSON and text forms people read.
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum FactorsView {
    /// Nominal geometry, no corrections.
    None,
    /// Differential drive (Borenstein & Feng).
    DiffDrive {
        /// Left wheel's effective radius / nominal radius.
        c_l: f64,
        /// Right wheel's effective radius / nominal radius.
        c_r: f64,
        /// Actual wheelbase / nominal wheelbase (in a turn in place, with a turn law).
        e_b: f64,
        /// The turn law: how much wider the separation is on arcs (absent: none).
        #[serde(skip_serializing_if = "Option::is_none")]
        e_b_arc: Option<f64>,
        /// The speed law: growth of the wheels' size per m/s (absent: none).
        #[serde(skip_serializing_if = "Option::is_none")]
        speed_rel: Option<f64>,
        /// The acceleration law: the ground's lag behind the wheels, s (absent: none).
        #[serde(skip_serializing_if = "Option::is_none")]
        accel_slip_s: Option<f64>,
        /// The motion the laws were fitted on, beyond which the board holds each law at
        /// its edge (absent: unbounded).
        #[serde(skip_serializing_if = "Option::is_none")]
        law_range: Option<LawRange>,
    },
    /// Omnidirectional robot.
    Omni {
        /// Lateral factor per wheel, in the robot's wheel order.
        f_lat: Vec<f64>,
        /// Longitudinal factor common to all wheels.
        f_lon: f64,
        /// The turn law: how much longer the wheels' distance from the centre is on arcs
        /// (absent: none).
        #[serde(skip_serializing_if = "Option::is_none")]
        l_arc: Option<f64>,
    },
}

impl From<&Corrections> for FactorsView {
    fn from(c: &Corrections) -> Self {
        match c {
            Corrections::None => FactorsView::None,
            Corrections::DiffDrive { .. }
            | Corrections::DiffDriveTurnLaw { .. }
            | Corrections::DiffDriveLaws { .. }
            | Corrections::DiffDriveLawsInRange { .. } => {
                let (c_l, c_r, e_b) = c.diff_factors().unwrap_or((1.0, 1.0, 1.0));
                let laws = c.laws();
                let some = |v: f64| (v != 0.0).then_some(v);
                FactorsView::DiffDrive {
                    c_l,
                    c_r,
                    e_b,
                    e_b_arc: some(laws.e_b_arc),
                    speed_rel: some(laws.speed_rel),
                    accel_slip_s: some(laws.accel_slip_s),
                    law_range: Some(c.law_range()).filter(|r| !r.is_unbounded()),
                }
            }
            Corrections::Omni { f_lat, f_lon } | Corrections::OmniTurnLaw { f_lat, f_lon, .. } => {
                FactorsView::Omni {
                    f_lat: f_lat.to_vec(),
                    f_lon: *f_lon,
                    l_arc: Some(c.l_arc()).filter(|&a| a != 0.0),
                }
            }
        }
    }
}

impl FactorsView {
    /// The factors as one text line.
    pub fn human(&self) -> String {
        match self {
            FactorsView::None => "no corrections (nominal geometry)\n".into(),
            FactorsView::DiffDrive {
                c_l,
                c_r,
                e_b,
                e_b_arc,
                speed_rel,
                accel_slip_s,
                law_range,
            } => {
                let mut s = format!("c_L = {c_l:.6}  c_R = {c_r:.6}  E_b = {e_b:.6}");
                if let Some(a) = e_b_arc {
                    s.push_str(&format!(
                        " in a turn in place, {:+.3} % wider on arcs (turn law e_b_arc {a:+.6})",
                        a * 100.0
                    ));
                }
                if let Some(v) = speed_rel {
                    s.push_str(&format!(
                        "; wheels {:+.3} % larger per m/s (speed law speed_rel {v:+.6}, c_L and c_R at standstill)",
                        v * 100.0
                    ));
                }
                if let Some(a) = accel_slip_s {
                    s.push_str(&format!(
                        "; the ground lags the wheels by {:.1} ms of their change of speed (acceleration law accel_slip_s {a:+.6})",
                        a * 1e3
                    ));
                }
                if let Some(r) = law_range {
                    s.push_str(&format!(
                        "; the laws held at their edges beyond the motion they were fitted on (turn ratio {:.3}-{:.3}, side speed up to {:.3} m/s)",
                        r.rho_min, r.rho_max, r.speed_max_m_s
                    ));
                }
                s.push('\n');
                s
            }
            FactorsView::Omni {
                f_lat,
                f_lon,
                l_arc,
            } => {
                let mut s = format!(
                    "F_lat = [{}]  F_lon = {f_lon:.6}",
                    f_lat
                        .iter()
                        .map(|v| format!("{v:.6}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                );
                if let Some(a) = l_arc {
                    s.push_str(&format!(
                        "  L_arc = {a:+.4}: the wheels' distance from the centre {:.1} % {} on arcs than in a turn in place (turn law)",
                        a.abs() * 100.0,
                        if *a >= 0.0 { "longer" } else { "shorter" }
                    ));
                }
                s.push('\n');
                s
            }
        }
    }
}

/// Why the board would refuse factors, in words, with the value as given: the board's
/// own message rounds to six decimals (`c_l = 2 is outside [0.5, 2]` for 2.0000001),
/// which hides why it is outside; here the value keeps every digit it was given with.
pub fn refusal_words(e: &calib_core::correction::CorrectionError) -> String {
    use calib_core::correction::{CorrectionError, FACTOR_MIN};
    match e {
        CorrectionError::OutOfRange {
            name,
            index,
            value,
            max,
        } => {
            let law = matches!(*name, "e_b_arc" | "speed_rel" | "accel_slip_s" | "l_arc");
            let min = if law {
                -*max
            } else if *name == "law_range" {
                0.0
            } else {
                FACTOR_MIN
            };
            let at = match index {
                Some(i) => format!("{name}[{i}]"),
                None => name.to_string(),
            };
            // Shortest digits that read back as the value (Rust's `{}` of f64); an
            // absurd magnitude in exponent form instead of hundreds of digits.
            let v = if value.abs() >= 1e9 || (*value != 0.0 && value.abs() < 1e-4) {
                format!("{value:e}")
            } else {
                format!("{value}")
            };
            format!("{at} = {v} is outside [{min}, {max}]")
        }
        other => other.to_string(),
    }
}

/// The factors `factors set` asks for: the board's `current` factors with the ones given
/// replaced (nominal where the board holds none or the other kind, `n_wheels` F_lat of 1
/// for an omni robot; the board refuses factors of the wrong kind in its own words).
/// Differential and omni factors do not mix, and at least one factor must be given. A
/// law (`e_b_arc`, `speed_rel`, `accel_slip_s`; an omni robot's `l_arc`) is kept unless
/// replaced; 0 removes it.
pub fn merge_corrections(
    current: &Corrections,
    n_wheels: usize,
    given: &GivenFactors<'_>,
) -> Result<Corrections> {
    let GivenFactors {
        c_l,
        c_r,
        e_b,
        e_b_arc,
        speed_rel,
        accel_slip_s,
        law_range,
        f_lat,
        f_lon,
        l_arc,
    } = *given;
    let diff = law_range.is_some()
        || c_l.is_some()
        || c_r.is_some()
        || e_b.is_some()
        || e_b_arc.is_some()
        || speed_rel.is_some()
        || accel_slip_s.is_some();
    let omni = f_lat.is_some() || f_lon.is_some() || l_arc.is_some();
    match (diff, omni) {
        (false, false) => bail!(
            "give the factors to change: --c-l, --c-r, --e-b, --e-b-arc, --speed-rel, --accel-slip-s (differential drive) or --f-lat, --f-lon, --l-arc (omni)"
        ),
        (true, true) => {
            bail!("differential (--c-l, --c-r, --e-b, --e-b-arc, --speed-rel, --accel-slip-s) and omni (--f-lat, --f-lon, --l-arc) factors do not mix")
        }
        (true, false) => {
            // Factors of the other kind on the board: nominal here, and the board refuses
            // differential factors on an omni robot in its own words.
            let (l, r, b) = current.diff_factors().unwrap_or((1.0, 1.0, 1.0));
            let (c_l, c_r, e_b) = (c_l.unwrap_or(l), c_r.unwrap_or(r), e_b.unwrap_or(b));
            let held = current.laws();
            let laws = DiffLaws {
                e_b_arc: e_b_arc.unwrap_or(held.e_b_arc),
                speed_rel: speed_rel.unwrap_or(held.speed_rel),
                accel_slip_s: accel_slip_s.unwrap_or(held.accel_slip_s),
            };
            let range = law_range.unwrap_or(current.law_range());
            Ok(Corrections::diff_drive_within(c_l, c_r, e_b, laws, range))
        }
        (false, true) => {
            let (lat, lon) = match current.omni_factors() {
                Some((f_lat, f_lon)) => (f_lat.to_vec(), f_lon),
                None => (vec![1.0; n_wheels], 1.0),
            };
            let lat = f_lat.map(<[f64]>::to_vec).unwrap_or(lat);
            let f_lat = heapless::Vec::from_slice(&lat)
                .map_err(|_| anyhow::anyhow!("at most {MAX_WHEELS} F_lat factors"))?;
            Ok(Corrections::omni(
                f_lat,
                f_lon.unwrap_or(lon),
                l_arc.unwrap_or(current.l_arc()),
            ))
        }
    }
}

/// The factors given on `factors set`'s command line (None: keep the board's).
#[derive(Debug, Clone, Copy, Default)]
pub struct GivenFactors<'a> {
    /// c_L.
    pub c_l: Option<f64>,
    /// c_R.
    pub c_r: Option<f64>,
    /// E_b (in a turn in place, with a turn law).
    pub e_b: Option<f64>,
    /// The turn law's e_b_arc (0: none).
    pub e_b_arc: Option<f64>,
    /// The speed law's speed_rel (0: none).
    pub speed_rel: Option<f64>,
    /// The acceleration law's accel_slip_s (0: none).
    pub accel_slip_s: Option<f64>,
    /// The motion the laws were fitted on (None: keep the board's).
    pub law_range: Option<LawRange>,
    /// F_lat, one per wheel.
    pub f_lat: Option<&'a [f64]>,
    /// F_lon.
    pub f_lon: Option<f64>,
    /// An omni robot's turn law l_arc (0: none).
    pub l_arc: Option<f64>,
}

/// A board's factors in words for messages (`c_L = 1.000000  c_R = ...`).
pub fn factors_text(c: &Corrections) -> String {
    FactorsView::from(c).human().trim_end().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `factors set --e-b 1.6` keeps the board's c_L and c_R (the help's promise); an
    /// omni robot with no factors gets F_lat 1 for the wheels not given.
    #[test]
    fn only_the_factors_given_change() {
        let cur = Corrections::DiffDrive {
            c_l: 0.998,
            c_r: 1.002,
            e_b: 1.01,
        };
        let m = merge_corrections(
            &cur,
            2,
            &GivenFactors {
                e_b: Some(1.6),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(
            m,
            Corrections::DiffDrive {
                c_l: 0.998,
                c_r: 1.002,
                e_b: 1.6
            }
        );
        let m = merge_corrections(
            &Corrections::None,
            2,
            &GivenFactors {
                c_l: Some(1.01),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(
            m,
            Corrections::DiffDrive {
                c_l: 1.01,
                c_r: 1.0,
                e_b: 1.0
            }
        );
        let m = merge_corrections(
            &Corrections::None,
            4,
            &GivenFactors {
                f_lon: Some(0.94),
                ..Default::default()
            },
        )
        .unwrap();
        match m {
            Corrections::Omni { f_lat, f_lon } => {
                assert_eq!(f_lat.as_slice(), &[1.0; 4]);
                assert_eq!(f_lon, 0.94);
            }
            other => panic!("{other:?}"),
        }
        // Mixing kinds or nothing given: refused, saying why.
        let e = merge_corrections(
            &cur,
            2,
            &GivenFactors {
                c_l: Some(1.0),
                f_lon: Some(1.0),
                ..Default::default()
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("do not mix"), "{e}");
        let e = merge_corrections(&cur, 2, &GivenFactors::default()).unwrap_err();
        assert!(e.to_string().contains("give the factors"), "{e}");
        // A turn law: added by --e-b-arc, kept by later --e-b, removed by --e-b-arc 0.
        let law = merge_corrections(
            &cur,
            2,
            &GivenFactors {
                e_b_arc: Some(0.0057),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(law.turn_law(), 0.0057);
        assert_eq!(law.diff_factors(), Some((0.998, 1.002, 1.01)));
        let kept = merge_corrections(
            &law,
            2,
            &GivenFactors {
                e_b: Some(1.02),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(kept.turn_law(), 0.0057);
        assert_eq!(kept.wheelbase_scale(), 1.02);
        let gone = merge_corrections(
            &kept,
            2,
            &GivenFactors {
                e_b_arc: Some(0.0),
                ..Default::default()
            },
        )
        .unwrap();
        assert!(matches!(gone, Corrections::DiffDrive { .. }), "{gone:?}");
    }

    /// `--speed-rel` and `--accel-slip-s` join a turn law already on the board (protocol
    /// v6's `DiffDriveLaws`), and removing them leaves the turn law as v5 boards hold it.
    /// The text names each law with its figure.
    #[test]
    fn speed_and_acceleration_laws_join_and_leave_a_turn_law() {
        let turn = Corrections::DiffDriveTurnLaw {
            c_l: 0.998,
            c_r: 1.002,
            e_b: 1.01,
            e_b_arc: 0.0057,
        };
        let all = merge_corrections(
            &turn,
            2,
            &GivenFactors {
                speed_rel: Some(-0.035),
                accel_slip_s: Some(0.047),
                ..Default::default()
            },
        )
        .unwrap();
        let l = all.laws();
        assert_eq!(
            (l.e_b_arc, l.speed_rel, l.accel_slip_s),
            (0.0057, -0.035, 0.047)
        );
        assert_eq!(all.diff_factors(), Some((0.998, 1.002, 1.01)));
        let text = factors_text(&all);
        assert!(text.contains("-3.500 % larger per m/s"), "{text}");
        assert!(text.contains("by 47.0 ms"), "{text}");
        let back = merge_corrections(
            &all,
            2,
            &GivenFactors {
                speed_rel: Some(0.0),
                accel_slip_s: Some(0.0),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(back, turn);
    }

    /// `--l-arc` alone on an omni board holding plain factors keeps its F_lat and F_lon
    /// and stores the turn law (protocol v8's `OmniTurnLaw`); a later `--f-lon` keeps the
    /// law; `--l-arc 0` leaves plain `Omni`, what older boards hold; `--l-arc` with a
    /// differential factor is refused. The text gives the law in per cent, the JSON as
    /// `l_arc` (absent without a law).
    #[test]
    fn an_omni_turn_law_joins_and_leaves_the_factors() {
        let plain = Corrections::Omni {
            f_lat: heapless::Vec::from_slice(&[1.01, 0.99, 1.0]).unwrap(),
            f_lon: 1.02,
        };
        let given = |l_arc, f_lon| GivenFactors {
            l_arc,
            f_lon,
            ..Default::default()
        };
        let law = merge_corrections(&plain, 3, &given(Some(0.019), None)).unwrap();
        assert_eq!(
            law,
            Corrections::OmniTurnLaw {
                f_lat: heapless::Vec::from_slice(&[1.01, 0.99, 1.0]).unwrap(),
                f_lon: 1.02,
                l_arc: 0.019,
            }
        );
        let kept = merge_corrections(&law, 3, &given(None, Some(0.97))).unwrap();
        assert_eq!(
            (kept.l_arc(), kept.omni_factors().unwrap().1),
            (0.019, 0.97)
        );
        let gone = merge_corrections(&kept, 3, &given(Some(0.0), None)).unwrap();
        assert!(
            matches!(gone, Corrections::Omni { f_lon, .. } if f_lon == 0.97),
            "{gone:?}"
        );
        let e = merge_corrections(
            &plain,
            3,
            &GivenFactors {
                e_b: Some(1.0),
                l_arc: Some(0.019),
                ..Default::default()
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("do not mix"), "{e}");
        let text = factors_text(&law);
        assert_eq!(
            text,
            "F_lat = [1.010000, 0.990000, 1.000000]  F_lon = 1.020000  L_arc = +0.0190: the wheels' distance from the centre 1.9 % longer on arcs than in a turn in place (turn law)"
        );
        let json = serde_json::to_value(FactorsView::from(&law)).unwrap();
        assert_eq!(json["kind"], "omni");
        assert_eq!(json["l_arc"], 0.019);
        let json = serde_json::to_value(FactorsView::from(&plain)).unwrap();
        assert!(json.get("l_arc").is_none(), "{json}");
        assert_eq!(json["f_lon"], 1.02);
    }
}
