//! Odometry corrections: Borenstein's c_L, c_R, E_b for differential drive and
//! [Redundant omni]'s F_lat, F_lon for omni robots.
//!
//! Both are expressed the same way underneath, as an effective radius multiplier per wheel
//! and a multiplier on the wheels' distance from the body origin. Kinematics built from
//! the corrected geometry is then used for wheel commands and odometry alike, which is
//! what "applied consistently" means: the robot is commanded and dead-reckoned with the
//! geometry it really has.

use crate::num::Num;
use crate::robot::{Robot, RobotKind, MAX_WHEELS};
use core::fmt;
use heapless::Vec;
use serde::{Deserialize, Serialize};

/// Factors outside this range are rejected: a real robot's wheels are not off by 2x.
pub const FACTOR_MIN: f64 = 0.5;
/// Factors above this are rejected (see [`FACTOR_MIN`]).
pub const FACTOR_MAX: f64 = 2.0;

/// A skid-steer robot's E_b may reach this: its effective separation is 1.5-2x the track
/// ([Mandow et al.]; Husky ships 1.875), so [`FACTOR_MAX`] would refuse every real one.
pub const SKID_EB_MAX: f64 = 3.0;

/// A turn law's e_b_arc (and an omni robot's l_arc) is refused beyond ±this: tyre scrub
/// widens a separation by a few per cent at most (the OptiOdom robot: 0.5 %; its omni
/// robot's rollers about 2 %).
pub const E_B_ARC_MAX: f64 = 0.1;

/// A speed law's speed_rel is refused beyond ±this (per m/s): calibration's plausible
/// range (a tyre that rolls 20 % further at 1 m/s is not a tyre).
pub const SPEED_REL_MAX: f64 = 0.2;

/// An acceleration law's accel_slip_s is refused beyond ±this (s): calibration's
/// plausible range.
pub const ACCEL_SLIP_MAX_S: f64 = 0.2;

/// A differential drive's laws of motion beyond constant factors, each fitted by
/// `wheelcal calibrate` when its data show it (0: no such law). The board's odometry
/// applies them ([`crate::diff_laws`]); wheel commands use the constant factors (the
/// closed loop on odometry steers the rest).
#[derive(
    Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, postcard_schema::Schema,
)]
pub struct DiffLaws {
    /// Turn law: how much wider the effective separation is on arcs than in a turn in
    /// place (0.005 is 0.5 %; [`crate::kinematics::turn_law_share`]).
    pub e_b_arc: f64,
    /// Speed law: growth of the wheels' effective size per m/s of their side's speed.
    pub speed_rel: f64,
    /// Acceleration law: the ground's lag behind each side's speed (s); each side's
    /// travel less accel_slip_s times its change of speed.
    pub accel_slip_s: f64,
}

impl DiffLaws {
    /// Two calibration passes' laws: small growths and lags add.
    pub fn plus(self, o: DiffLaws) -> DiffLaws {
        DiffLaws {
            e_b_arc: self.e_b_arc + o.e_b_arc,
            speed_rel: self.speed_rel + o.speed_rel,
            accel_slip_s: self.accel_slip_s + o.accel_slip_s,
        }
    }

    /// Each law finite and within its range (±[`E_B_ARC_MAX`], ±[`SPEED_REL_MAX`],
    /// ±[`ACCEL_SLIP_MAX_S`]).
    pub fn validate(&self) -> Result<(), CorrectionError> {
        check_within("e_b_arc", self.e_b_arc, -E_B_ARC_MAX, E_B_ARC_MAX)?;
        check_within("speed_rel", self.speed_rel, -SPEED_REL_MAX, SPEED_REL_MAX)?;
        check_within(
            "accel_slip_s",
            self.accel_slip_s,
            -ACCEL_SLIP_MAX_S,
            ACCEL_SLIP_MAX_S,
        )
    }
}

/// The motion a differential drive's laws were fitted on ([`Corrections::DiffDriveLawsInRange`]):
/// beyond it the odometry holds each law at its value at the edge, never extrapolating it
/// to speeds, turns or accelerations the calibration did not see. Unbounded
/// ([`LawRange::UNBOUNDED`]): every law applied as fitted at any motion (what boards before
/// protocol v9 do).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct LawRange {
    /// Smallest turn ratio rho (0 straight, 1 a turn in place) the turn law was fitted on.
    pub rho_min: f32,
    /// Largest turn ratio rho.
    pub rho_max: f32,
    /// Fastest side speed |v| (m/s) the speed and acceleration laws were fitted on:
    /// beyond it the speed law holds its value there, and the acceleration law's lag
    /// (its changes of speed summed: accel_slip_s times the speed) stops growing.
    pub speed_max_m_s: f32,
}

impl LawRange {
    /// Every motion: the laws applied as fitted.
    pub const UNBOUNDED: LawRange = LawRange {
        rho_min: 0.0,
        rho_max: 1.0,
        speed_max_m_s: f32::INFINITY,
    };

    /// Whether this is [`LawRange::UNBOUNDED`] (or wider).
    pub fn is_unbounded(&self) -> bool {
        self.rho_min <= 0.0 && self.rho_max >= 1.0 && self.speed_max_m_s == f32::INFINITY
    }

    /// This range less the bounds of laws `laws` lacks (a bound of no law is no bound).
    pub fn for_laws(self, laws: &DiffLaws) -> LawRange {
        let u = LawRange::UNBOUNDED;
        LawRange {
            rho_min: if laws.e_b_arc != 0.0 {
                self.rho_min
            } else {
                u.rho_min
            },
            rho_max: if laws.e_b_arc != 0.0 {
                self.rho_max
            } else {
                u.rho_max
            },
            speed_max_m_s: if laws.speed_rel != 0.0 || laws.accel_slip_s != 0.0 {
                self.speed_max_m_s
            } else {
                u.speed_max_m_s
            },
        }
    }

    /// The smallest range holding both.
    pub fn hull(self, o: LawRange) -> LawRange {
        LawRange {
            rho_min: self.rho_min.min(o.rho_min),
            rho_max: self.rho_max.max(o.rho_max),
            speed_max_m_s: self.speed_max_m_s.max(o.speed_max_m_s),
        }
    }

    /// 0 <= rho_min <= rho_max <= 1, the speed and acceleration not negative (infinite
    /// allowed), nothing NaN (one comparison chain, in f32 as the board takes it: NaN
    /// fails it). Refused as `law_range`, its value rho_min.
    pub fn validate(&self) -> Result<(), CorrectionError> {
        let r = self;
        if 0.0 <= r.rho_min && r.rho_min <= r.rho_max && r.rho_max <= 1.0 && r.speed_max_m_s >= 0.0
        {
            return Ok(());
        }
        Err(CorrectionError::OutOfRange {
            name: "law_range",
            index: None,
            value: r.rho_min as f64,
            max: 1.0,
        })
    }
}

impl Default for LawRange {
    fn default() -> Self {
        LawRange::UNBOUNDED
    }
}

/// The correction factors a board stores.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum Corrections {
    /// Nominal geometry.
    None,
    /// Borenstein & Feng: effective left/right radius multipliers and actual/nominal
    /// wheelbase.
    DiffDrive {
        /// Left wheel's effective radius / nominal radius.
        c_l: f64,
        /// Right wheel's effective radius / nominal radius.
        c_r: f64,
        /// Actual wheelbase / nominal wheelbase (Borenstein's E_b).
        e_b: f64,
    },
    /// [Redundant omni] eq. 6: wheel command = `f_lon * f_lat[i] * (J * twist)_i`.
    Omni {
        /// Lateral factor per wheel, in the robot's wheel order (dimensionless).
        f_lat: Vec<f64, MAX_WHEELS>,
        /// Longitudinal factor common to all wheels (dimensionless).
        f_lon: f64,
    },
    /// [`Corrections::DiffDrive`] whose effective separation depends on the turn (wide
    /// tyres' turn slip, fitted by `wheelcal calibrate`): `e_b` in a turn in place, times
    /// 1 + `e_b_arc` (1 - rho^2) at turn ratio rho ([`crate::kinematics::turn_law_share`]).
    /// Odometry applies the law; wheel commands use `e_b` (the closed loop on odometry
    /// steers the rest). Last on the wire, so stored and sent values of the other kinds
    /// read as before.
    DiffDriveTurnLaw {
        /// Left wheel's effective radius / nominal radius.
        c_l: f64,
        /// Right wheel's effective radius / nominal radius.
        c_r: f64,
        /// Actual wheelbase / nominal wheelbase in a turn in place.
        e_b: f64,
        /// How much wider the effective separation is on arcs (0.005 is 0.5 %).
        e_b_arc: f64,
    },
    /// [`Corrections::DiffDrive`] with any of a differential drive's laws ([`DiffLaws`]:
    /// turn, speed, acceleration), applied by the odometry ([`crate::diff_laws`]).
    /// Protocol v6; last on the wire, so stored and sent values of the other kinds read as
    /// before. [`Corrections::diff_drive`] gives a turn law alone as
    /// [`Corrections::DiffDriveTurnLaw`], which v5 boards understand.
    DiffDriveLaws {
        /// Left wheel's effective radius / nominal radius (at standstill, with a speed
        /// law).
        c_l: f64,
        /// Right wheel's effective radius / nominal radius (likewise).
        c_r: f64,
        /// Actual wheelbase / nominal wheelbase (in a turn in place, with a turn law).
        e_b: f64,
        /// The laws.
        laws: DiffLaws,
    },
    /// [`Corrections::Omni`] whose wheels' effective distance from the centre is longer on
    /// arcs than in a turn in place (the contact moving across the rollers: the OptiOdom
    /// omni3 turns 1.4-2 % less per wheel turn on 0.7 m arcs than in spins). Odometry
    /// divides each tick's turn by 1 + `l_arc` (1 - rho^2) at its turn ratio rho
    /// ([`crate::omni_laws`]); wheel commands use the plain factors. Protocol v8; last on
    /// the wire, so stored and sent values of the other kinds read as before.
    OmniTurnLaw {
        /// Lateral factor per wheel, in the robot's wheel order (dimensionless).
        f_lat: Vec<f64, MAX_WHEELS>,
        /// Longitudinal factor common to all wheels (dimensionless).
        f_lon: f64,
        /// How much longer the wheels' effective distance from the centre is on arcs
        /// (0.02 is 2 %).
        l_arc: f64,
    },
    /// [`Corrections::DiffDriveLaws`] with the motion the laws were fitted on
    /// ([`LawRange`]): beyond it the odometry holds each law at its edge. Protocol v9;
    /// last on the wire, so stored and sent values of the other kinds read as before
    /// (they apply their laws unbounded). [`Corrections::diff_drive_within`] gives an
    /// unbounded range as the narrower kinds.
    DiffDriveLawsInRange {
        /// Left wheel's effective radius / nominal radius (at standstill, with a speed
        /// law).
        c_l: f64,
        /// Right wheel's effective radius / nominal radius (likewise).
        c_r: f64,
        /// Actual wheelbase / nominal wheelbase (in a turn in place, with a turn law).
        e_b: f64,
        /// The laws.
        laws: DiffLaws,
        /// Where they were fitted ([`LawRange`]'s fields, in its order: one struct less
        /// to encode on the board): the smallest and largest turn ratio, the fastest side
        /// (m/s).
        range: [f32; 3],
    },
}

/// Why a set of factors was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum CorrectionError {
    /// Factor `name` (index for f_lat) is NaN or infinite.
    NotFinite {
        /// Name of the factor (`c_l`, `f_lat`, ...).
        name: &'static str,
        /// Wheel index for per-wheel factors (`f_lat`), `None` otherwise.
        index: Option<usize>,
    },
    /// Factor outside [0.5, max].
    OutOfRange {
        /// Name of the factor.
        name: &'static str,
        /// Wheel index for per-wheel factors (`f_lat`), `None` otherwise.
        index: Option<usize>,
        /// The rejected value.
        value: f64,
        /// The upper bound that applied ([`FACTOR_MAX`], or [`SKID_EB_MAX`] for a
        /// skid-steer robot's E_b).
        max: f64,
    },
    /// Omni factors need one f_lat per wheel.
    WrongWheelCount {
        /// Wheels the robot has.
        expected: usize,
        /// Factors given.
        got: usize,
    },
    /// Differential factors on an omni robot or the reverse.
    /// The robot's kind, which the factors do not fit.
    WrongKind {
        /// The robot's kind, which the factors do not fit.
        robot: RobotKind,
    },
}

impl fmt::Display for CorrectionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let at = |f: &mut fmt::Formatter<'_>, name: &str, index: &Option<usize>| match index {
            Some(i) => write!(f, "{name}[{i}]"),
            None => write!(f, "{name}"),
        };
        match self {
            CorrectionError::NotFinite { name, index } => {
                at(f, name, index)?;
                write!(f, " must be a finite number")
            }
            CorrectionError::OutOfRange {
                name,
                index,
                value,
                max,
            } => {
                at(f, name, index)?;
                // A law (e_b_arc, speed_rel, accel_slip_s) is symmetric about 0; factors
                // start at FACTOR_MIN.
                let law = matches!(*name, "e_b_arc" | "speed_rel" | "accel_slip_s" | "l_arc");
                let min = if law { -*max } else { FACTOR_MIN };
                write!(
                    f,
                    " = {} is outside [{}, {}]",
                    Num(*value),
                    Num(min),
                    Num(*max)
                )
            }
            CorrectionError::WrongWheelCount { expected, got } => {
                write!(f, "f_lat needs one factor per wheel: {expected}, got {got}")
            }
            CorrectionError::WrongKind { robot } => write!(
                f,
                "these factors do not fit this {} robot (diff_drive takes c_l, c_r, e_b; omni takes f_lat, f_lon, l_arc)",
                robot.as_str()
            ),
        }
    }
}

impl core::error::Error for CorrectionError {}

/// The board's rule for one factor: finite and within [[`FACTOR_MIN`], [`FACTOR_MAX`]].
/// Every tool that writes factors anywhere (the board, a ROS 2 file) applies this one.
pub fn check(name: &'static str, index: Option<usize>, v: f64) -> Result<(), CorrectionError> {
    if !v.is_finite() {
        return Err(CorrectionError::NotFinite { name, index });
    }
    if !(FACTOR_MIN..=FACTOR_MAX).contains(&v) {
        return Err(CorrectionError::OutOfRange {
            name,
            index,
            value: v,
            max: FACTOR_MAX,
        });
    }
    Ok(())
}

/// [`check`] with another upper bound (a skid-steer robot's E_b: [`SKID_EB_MAX`]).
pub fn check_within(name: &'static str, v: f64, min: f64, max: f64) -> Result<(), CorrectionError> {
    if !v.is_finite() {
        return Err(CorrectionError::NotFinite { name, index: None });
    }
    if !(min..=max).contains(&v) {
        return Err(CorrectionError::OutOfRange {
            name,
            index: None,
            value: v,
            max,
        });
    }
    Ok(())
}

impl Corrections {
    /// No correction (nominal geometry); usable in `const` context.
    pub const fn none() -> Self {
        Corrections::None
    }

    /// A differential drive's factors with `laws`, as the narrowest kind that holds them:
    /// plain factors without a law, [`Corrections::DiffDriveTurnLaw`] for a turn law
    /// alone (what boards of protocol v5 take), else [`Corrections::DiffDriveLaws`].
    pub fn diff_drive(c_l: f64, c_r: f64, e_b: f64, laws: DiffLaws) -> Corrections {
        if laws == DiffLaws::default() {
            Corrections::DiffDrive { c_l, c_r, e_b }
        } else if laws.speed_rel == 0.0 && laws.accel_slip_s == 0.0 {
            Corrections::DiffDriveTurnLaw {
                c_l,
                c_r,
                e_b,
                e_b_arc: laws.e_b_arc,
            }
        } else {
            Corrections::DiffDriveLaws {
                c_l,
                c_r,
                e_b,
                laws,
            }
        }
    }

    /// [`Corrections::diff_drive`] with the motion the laws were fitted on:
    /// [`Corrections::DiffDriveLawsInRange`] when there is a law and the range bounds one
    /// of them ([`LawRange::for_laws`]).
    pub fn diff_drive_within(
        c_l: f64,
        c_r: f64,
        e_b: f64,
        laws: DiffLaws,
        range: LawRange,
    ) -> Corrections {
        let range = range.for_laws(&laws);
        if laws == DiffLaws::default() || range.is_unbounded() {
            Corrections::diff_drive(c_l, c_r, e_b, laws)
        } else {
            Corrections::DiffDriveLawsInRange {
                c_l,
                c_r,
                e_b,
                laws,
                range: [range.rho_min, range.rho_max, range.speed_max_m_s],
            }
        }
    }

    /// An omni robot's factors with a turn law `l_arc`, as the narrowest kind that holds
    /// them: plain [`Corrections::Omni`] without a law (what boards before protocol v8
    /// take), else [`Corrections::OmniTurnLaw`].
    pub fn omni(f_lat: Vec<f64, MAX_WHEELS>, f_lon: f64, l_arc: f64) -> Corrections {
        if l_arc == 0.0 {
            Corrections::Omni { f_lat, f_lon }
        } else {
            Corrections::OmniTurnLaw {
                f_lat,
                f_lon,
                l_arc,
            }
        }
    }

    /// Checks the factors are finite, within [0.5, 2.0] and fit the robot (a
    /// differential drive's laws within their ranges ([`DiffLaws::validate`]), on a
    /// differential drive only; an omni robot's l_arc within ±[`E_B_ARC_MAX`], on an omni
    /// robot only).
    pub fn validate(&self, robot: &Robot) -> Result<(), CorrectionError> {
        match self {
            Corrections::None => Ok(()),
            Corrections::DiffDriveTurnLaw { c_l, c_r, e_b, .. }
            | Corrections::DiffDriveLaws { c_l, c_r, e_b, .. }
            | Corrections::DiffDriveLawsInRange { c_l, c_r, e_b, .. } => {
                if robot.kind != RobotKind::DiffDrive {
                    return Err(CorrectionError::WrongKind { robot: robot.kind });
                }
                check("c_l", None, *c_l)?;
                check("c_r", None, *c_r)?;
                check("e_b", None, *e_b)?;
                self.laws().validate()?;
                // The range on the array itself (no struct built on the board): its turn
                // ratios in order and its speed not negative, nothing NaN. Bounds past
                // 0 or 1 bind nothing (rho is within 0..1), so they are taken as given.
                if let Corrections::DiffDriveLawsInRange {
                    range: [lo, hi, v], ..
                } = self
                {
                    if !(lo <= hi && *v >= 0.0) {
                        return Err(CorrectionError::OutOfRange {
                            name: "law_range",
                            index: None,
                            value: *lo as f64,
                            max: 1.0,
                        });
                    }
                }
                Ok(())
            }
            Corrections::DiffDrive { c_l, c_r, e_b } => {
                if robot.kind == RobotKind::Omni {
                    return Err(CorrectionError::WrongKind { robot: robot.kind });
                }
                check("c_l", None, *c_l)?;
                check("c_r", None, *c_r)?;
                if robot.kind == RobotKind::SkidSteer {
                    check_within("e_b", *e_b, FACTOR_MIN, SKID_EB_MAX)
                } else {
                    check("e_b", None, *e_b)
                }
            }
            Corrections::Omni { f_lat, f_lon } | Corrections::OmniTurnLaw { f_lat, f_lon, .. } => {
                if robot.kind != RobotKind::Omni {
                    return Err(CorrectionError::WrongKind { robot: robot.kind });
                }
                if f_lat.len() != robot.wheel_count() {
                    return Err(CorrectionError::WrongWheelCount {
                        expected: robot.wheel_count(),
                        got: f_lat.len(),
                    });
                }
                for (i, f) in f_lat.iter().enumerate() {
                    check("f_lat", Some(i), *f)?;
                }
                check("f_lon", None, *f_lon)?;
                check_within("l_arc", self.l_arc(), -E_B_ARC_MAX, E_B_ARC_MAX)
            }
        }
    }

    /// Effective radius multiplier of wheel `i`. For omni, a wheel commanded at
    /// f_lon * f_lat times nominal behaves as if its radius were nominal / (f_lon * f_lat).
    pub fn radius_scale(&self, robot: &Robot, i: usize) -> f64 {
        match self {
            Corrections::None => 1.0,
            Corrections::DiffDrive { c_l, c_r, .. }
            | Corrections::DiffDriveTurnLaw { c_l, c_r, .. }
            | Corrections::DiffDriveLaws { c_l, c_r, .. }
            | Corrections::DiffDriveLawsInRange { c_l, c_r, .. } => {
                if robot.wheels[i].is_left() {
                    *c_l
                } else {
                    *c_r
                }
            }
            Corrections::Omni { f_lat, f_lon } | Corrections::OmniTurnLaw { f_lat, f_lon, .. } => {
                1.0 / (f_lon * f_lat.get(i).copied().unwrap_or(1.0))
            }
        }
    }

    /// Multiplier on every wheel's distance from the body origin (E_b; with a turn law,
    /// its value in a turn in place).
    pub fn wheelbase_scale(&self) -> f64 {
        match self {
            Corrections::DiffDrive { e_b, .. }
            | Corrections::DiffDriveTurnLaw { e_b, .. }
            | Corrections::DiffDriveLaws { e_b, .. }
            | Corrections::DiffDriveLawsInRange { e_b, .. } => *e_b,
            _ => 1.0,
        }
    }

    /// A differential drive's (c_l, c_r, e_b), with or without a turn law.
    pub fn diff_factors(&self) -> Option<(f64, f64, f64)> {
        match self {
            Corrections::DiffDrive { c_l, c_r, e_b }
            | Corrections::DiffDriveTurnLaw { c_l, c_r, e_b, .. }
            | Corrections::DiffDriveLaws { c_l, c_r, e_b, .. }
            | Corrections::DiffDriveLawsInRange { c_l, c_r, e_b, .. } => Some((*c_l, *c_r, *e_b)),
            _ => None,
        }
    }

    /// A differential drive's laws (all 0 without any).
    #[inline(never)]
    pub fn laws(&self) -> DiffLaws {
        match self {
            Corrections::DiffDriveTurnLaw { e_b_arc, .. } => DiffLaws {
                e_b_arc: *e_b_arc,
                ..DiffLaws::default()
            },
            Corrections::DiffDriveLaws { laws, .. }
            | Corrections::DiffDriveLawsInRange { laws, .. } => *laws,
            _ => DiffLaws::default(),
        }
    }

    /// Where a differential drive's laws were fitted ([`LawRange::UNBOUNDED`] for kinds
    /// that carry no range).
    pub fn law_range(&self) -> LawRange {
        match self {
            Corrections::DiffDriveLawsInRange { range: r, .. } => LawRange {
                rho_min: r[0],
                rho_max: r[1],
                speed_max_m_s: r[2],
            },
            _ => LawRange::UNBOUNDED,
        }
    }

    /// The turn law's e_b_arc (0 without one).
    pub fn turn_law(&self) -> f64 {
        self.laws().e_b_arc
    }

    /// An omni robot's (f_lat, f_lon), with or without a turn law.
    pub fn omni_factors(&self) -> Option<(&[f64], f64)> {
        match self {
            Corrections::Omni { f_lat, f_lon } | Corrections::OmniTurnLaw { f_lat, f_lon, .. } => {
                Some((f_lat, *f_lon))
            }
            _ => None,
        }
    }

    /// An omni robot's turn law l_arc (0 without one, and for every other kind).
    pub fn l_arc(&self) -> f64 {
        match self {
            Corrections::OmniTurnLaw { l_arc, .. } => *l_arc,
            _ => 0.0,
        }
    }

    /// A second calibration pass ([Redundant omni]): runs measured with `self` in force give
    /// `secondary`, which measures only what `self` left; every multiplier of the two
    /// multiplies. `None` for factors of different kinds or wheel counts.
    pub fn compose(&self, secondary: &Corrections) -> Option<Corrections> {
        match (self, secondary) {
            (Corrections::None, s) => Some(s.clone()),
            (p, Corrections::None) => Some(p.clone()),
            // Omni factors multiply; the turn laws' small growths add.
            (p, s) if p.omni_factors().is_some() && s.omni_factors().is_some() => {
                let ((l1, o1), (l2, o2)) = (p.omni_factors()?, s.omni_factors()?);
                (l1.len() == l2.len()).then(|| {
                    Corrections::omni(
                        l1.iter().zip(l2).map(|(a, b)| a * b).collect(),
                        o1 * o2,
                        p.l_arc() + s.l_arc(),
                    )
                })
            }
            // Differential factors multiply; the laws' small growths and lags add.
            // Anything else (omni with differential, or other wheel counts) does not
            // compose.
            _ => {
                let (l1, r1, b1) = self.diff_factors()?;
                let (l2, r2, b2) = secondary.diff_factors()?;
                // The second pass's range when it has one (its laws were fitted on it).
                let range = if secondary.law_range().is_unbounded() {
                    self.law_range()
                } else {
                    secondary.law_range()
                };
                Some(Corrections::diff_drive_within(
                    l1 * l2,
                    r1 * r2,
                    b1 * b2,
                    self.laws().plus(secondary.laws()),
                    range,
                ))
            }
        }
    }

    /// Factors of one with these corrections' laws, for `wheels` wheels: what a board
    /// holds beside a robot file that carries the factors' geometry itself
    /// (`calibrate --write-board-robot`, the omni circle test's robot), so that the
    /// geometry is not counted twice and the laws, which no robot file carries, stay.
    pub fn laws_only(&self, wheels: usize) -> Corrections {
        match self {
            Corrections::None => Corrections::None,
            Corrections::Omni { .. } | Corrections::OmniTurnLaw { .. } => Corrections::omni(
                core::iter::repeat_n(1.0, wheels.min(MAX_WHEELS)).collect(),
                1.0,
                self.l_arc(),
            ),
            _ => Corrections::diff_drive_within(1.0, 1.0, 1.0, self.laws(), self.law_range()),
        }
    }

    /// The robot with the corrected geometry: what calibration says it really is.
    pub fn apply_to(&self, robot: &Robot) -> Robot {
        let mut out = robot.clone();
        let eb = self.wheelbase_scale();
        for (i, w) in out.wheels.iter_mut().enumerate() {
            w.radius_m *= self.radius_scale(robot, i);
            w.l_m *= eb;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::presets;

    /// Factors of one keep the laws to the bit and change no geometry: an omni robot's
    /// l_arc, a differential drive's three laws, plain factors giving plain ones.
    #[test]
    fn laws_only_keeps_the_laws_and_no_geometry() {
        let omni = Corrections::omni(Vec::from_slice(&[1.02, 0.98, 1.01]).unwrap(), 1.03, 0.019);
        assert_eq!(
            omni.laws_only(3),
            Corrections::omni(Vec::from_slice(&[1.0; 3]).unwrap(), 1.0, 0.019)
        );
        let laws = DiffLaws {
            e_b_arc: 0.006,
            speed_rel: -0.02,
            accel_slip_s: 0.01,
        };
        let diff = Corrections::diff_drive(1.01, 0.99, 1.02, laws);
        let ones = diff.laws_only(2);
        assert_eq!(ones, Corrections::diff_drive(1.0, 1.0, 1.0, laws));
        let r = presets::mobolab();
        assert_eq!(ones.apply_to(&r), r);
        assert_eq!(
            Corrections::DiffDrive {
                c_l: 1.1,
                c_r: 0.9,
                e_b: 1.2
            }
            .laws_only(2),
            Corrections::DiffDrive {
                c_l: 1.0,
                c_r: 1.0,
                e_b: 1.0
            }
        );
        assert_eq!(Corrections::None.laws_only(3), Corrections::None);
    }

    /// A second pass over a turn law: the factors multiply, the laws add (to 1e-12),
    /// laws that cancel leave plain factors, and omni with differential factors does not
    /// compose.
    #[test]
    fn turn_laws_compose() {
        let law = |e_b_arc| Corrections::DiffDriveTurnLaw {
            c_l: 1.01,
            c_r: 0.99,
            e_b: 1.02,
            e_b_arc,
        };
        let plain = Corrections::DiffDrive {
            c_l: 1.002,
            c_r: 0.998,
            e_b: 1.005,
        };
        let c = law(0.005).compose(&plain).unwrap();
        let (l, r, b) = c.diff_factors().unwrap();
        assert!((l - 1.01 * 1.002).abs() < 1e-12 && (r - 0.99 * 0.998).abs() < 1e-12);
        assert!((b - 1.02 * 1.005).abs() < 1e-12);
        assert!((c.turn_law() - 0.005).abs() < 1e-12);
        let c = law(0.005).compose(&law(0.002)).unwrap();
        assert!((c.turn_law() - 0.007).abs() < 1e-12);
        assert!(matches!(
            law(0.005).compose(&law(-0.005)),
            Some(Corrections::DiffDrive { .. })
        ));
        let omni = Corrections::Omni {
            f_lat: Vec::from_slice(&[1.0, 1.0, 1.0]).unwrap(),
            f_lon: 1.0,
        };
        assert_eq!(law(0.005).compose(&omni), None);
    }

    /// A differential drive's laws: each is refused past its range with its name (and
    /// the symmetric range in words), not on an omni robot; laws of two passes add (to
    /// 1e-12); the narrowest kind holds them (a turn law alone stays v5's
    /// `DiffDriveTurnLaw`, no law is plain factors).
    #[test]
    fn laws_are_checked_compose_and_take_the_narrowest_kind() {
        let dd = presets::mobolab();
        let with = |speed_rel, accel_slip_s| {
            Corrections::diff_drive(
                1.0,
                1.0,
                1.0,
                DiffLaws {
                    e_b_arc: 0.0,
                    speed_rel,
                    accel_slip_s,
                },
            )
        };
        assert_eq!(with(0.1, -0.05).validate(&dd), Ok(()));
        let e = with(0.25, 0.0).validate(&dd).unwrap_err();
        assert_eq!(
            e,
            CorrectionError::OutOfRange {
                name: "speed_rel",
                index: None,
                value: 0.25,
                max: SPEED_REL_MAX,
            }
        );
        assert_eq!(
            std::format!("{e}"),
            "speed_rel = 0.25 is outside [-0.2, 0.2]"
        );
        assert!(matches!(
            with(0.0, f64::NAN).validate(&dd),
            Err(CorrectionError::NotFinite {
                name: "accel_slip_s",
                ..
            })
        ));
        assert!(matches!(
            with(0.0, -0.3).validate(&dd),
            Err(CorrectionError::OutOfRange {
                name: "accel_slip_s",
                ..
            })
        ));
        assert!(matches!(
            with(0.1, 0.0).validate(&presets::omni4()),
            Err(CorrectionError::WrongKind { .. })
        ));
        let c = with(0.1, 0.02).compose(&with(-0.03, 0.01)).unwrap();
        let l = c.laws();
        assert!((l.speed_rel - 0.07).abs() < 1e-12 && (l.accel_slip_s - 0.03).abs() < 1e-12);
        assert!(matches!(c, Corrections::DiffDriveLaws { .. }));
        assert!(matches!(
            with(0.1, 0.0).compose(&with(-0.1, 0.0)),
            Some(Corrections::DiffDrive { .. })
        ));
        let turn = DiffLaws {
            e_b_arc: 0.005,
            ..DiffLaws::default()
        };
        assert!(matches!(
            Corrections::diff_drive(1.0, 1.0, 1.0, turn),
            Corrections::DiffDriveTurnLaw { e_b_arc, .. } if e_b_arc == 0.005
        ));
    }

    #[test]
    fn range_and_kind_are_checked() {
        let dd = presets::mobolab();
        let ok = Corrections::DiffDrive {
            c_l: 1.01,
            c_r: 0.99,
            e_b: 1.05,
        };
        assert_eq!(ok.validate(&dd), Ok(()));
        let bad = Corrections::DiffDrive {
            c_l: 2.5,
            c_r: 0.99,
            e_b: 1.0,
        };
        assert_eq!(
            bad.validate(&dd),
            Err(CorrectionError::OutOfRange {
                name: "c_l",
                index: None,
                value: 2.5,
                max: FACTOR_MAX,
            })
        );
        // A skid-steer robot's E_b may reach SKID_EB_MAX (a long-wheelbase rover reaches
        // 2.4); a differential drive's may not.
        let skid = presets::skid4("rover", 0.1, 0.4, 0.31, Default::default());
        let husky = Corrections::DiffDrive {
            c_l: 1.0,
            c_r: 1.0,
            e_b: 2.4,
        };
        assert_eq!(husky.validate(&skid), Ok(()));
        assert!(husky.validate(&dd).is_err());
        let wide = Corrections::DiffDrive {
            c_l: 1.0,
            c_r: 1.0,
            e_b: 3.5,
        };
        assert_eq!(
            wide.validate(&skid),
            Err(CorrectionError::OutOfRange {
                name: "e_b",
                index: None,
                value: 3.5,
                max: SKID_EB_MAX,
            })
        );
        let nan = Corrections::DiffDrive {
            c_l: 1.0,
            c_r: f64::NAN,
            e_b: 1.0,
        };
        assert!(matches!(
            nan.validate(&dd),
            Err(CorrectionError::NotFinite { name: "c_r", .. })
        ));
        let omni = presets::omni4();
        assert!(matches!(
            ok.validate(&omni),
            Err(CorrectionError::WrongKind { .. })
        ));
        let f = Corrections::Omni {
            f_lat: Vec::from_slice(&[1.0, 1.0, 1.0]).unwrap(),
            f_lon: 1.0,
        };
        assert_eq!(
            f.validate(&omni),
            Err(CorrectionError::WrongWheelCount {
                expected: 4,
                got: 3
            })
        );
    }

    /// An omni robot's turn law: refused past ±E_B_ARC_MAX with its name, and on a
    /// differential drive; the wheel geometry is the plain factors' (the law is odometry
    /// only); two passes' factors multiply and their l_arc add (to 1e-12); a law that
    /// cancels leaves plain `Omni`, what boards before v8 read.
    #[test]
    fn an_omni_turn_law_is_checked_and_composes() {
        let omni = presets::omni3(0.04, 0.15);
        let f =
            |l_arc| Corrections::omni(Vec::from_slice(&[1.01, 0.99, 1.0]).unwrap(), 1.02, l_arc);
        let law = f(0.019);
        assert!(matches!(law, Corrections::OmniTurnLaw { l_arc, .. } if l_arc == 0.019));
        assert!(matches!(f(0.0), Corrections::Omni { .. }));
        assert_eq!(law.validate(&omni), Ok(()));
        assert_eq!(
            (law.l_arc(), f(0.0).l_arc(), Corrections::None.l_arc()),
            (0.019, 0.0, 0.0)
        );
        assert_eq!(law.omni_factors(), Some((&[1.01, 0.99, 1.0][..], 1.02)));
        let e = f(0.15).validate(&omni).unwrap_err();
        assert_eq!(
            e,
            CorrectionError::OutOfRange {
                name: "l_arc",
                index: None,
                value: 0.15,
                max: E_B_ARC_MAX,
            }
        );
        assert_eq!(std::format!("{e}"), "l_arc = 0.15 is outside [-0.1, 0.1]");
        assert!(matches!(
            f(f64::INFINITY).validate(&omni),
            Err(CorrectionError::NotFinite { name: "l_arc", .. })
        ));
        assert!(matches!(
            law.validate(&presets::mobolab()),
            Err(CorrectionError::WrongKind { .. })
        ));
        assert!(matches!(
            Corrections::OmniTurnLaw {
                f_lat: Vec::from_slice(&[1.0; 4]).unwrap(),
                f_lon: 1.0,
                l_arc: 0.01,
            }
            .validate(&omni),
            Err(CorrectionError::WrongWheelCount {
                expected: 3,
                got: 4
            })
        ));
        assert_eq!(law.apply_to(&omni), f(0.0).apply_to(&omni));
        let c = law.compose(&f(0.002)).unwrap();
        let (l, o) = c.omni_factors().unwrap();
        assert!((l[0] - 1.01 * 1.01).abs() < 1e-12 && (o - 1.02 * 1.02).abs() < 1e-12);
        assert!((c.l_arc() - 0.021).abs() < 1e-12);
        assert!(matches!(
            law.compose(&f(-0.019)),
            Some(Corrections::Omni { .. })
        ));
        assert_eq!(law.compose(&presets_diff()), None);
    }

    fn presets_diff() -> Corrections {
        Corrections::DiffDrive {
            c_l: 1.0,
            c_r: 1.0,
            e_b: 1.0,
        }
    }

    #[test]
    fn second_pass_multiplies() {
        let first = Corrections::DiffDrive {
            c_l: 1.01,
            c_r: 0.99,
            e_b: 1.02,
        };
        let second = Corrections::DiffDrive {
            c_l: 1.001,
            c_r: 0.998,
            e_b: 0.995,
        };
        let Some(Corrections::DiffDrive { c_l, c_r, e_b }) = first.compose(&second) else {
            panic!()
        };
        assert!(
            (c_l - 1.01 * 1.001).abs() < 1e-15
                && (c_r - 0.99 * 0.998).abs() < 1e-15
                && (e_b - 1.02 * 0.995).abs() < 1e-15
        );
        let omni = |f: &[f64], lon: f64| Corrections::Omni {
            f_lat: Vec::from_slice(f).unwrap(),
            f_lon: lon,
        };
        let c = omni(&[1.1, 0.9, 1.0, 1.0], 1.05)
            .compose(&omni(&[0.95, 1.05, 1.0, 1.02], 0.98))
            .unwrap();
        assert_eq!(c, omni(&[1.1 * 0.95, 0.9 * 1.05, 1.0, 1.02], 1.05 * 0.98));
        assert_eq!(Corrections::None.compose(&first), Some(first.clone()));
        assert_eq!(first.compose(&omni(&[1.0; 4], 1.0)), None);
        assert_eq!(omni(&[1.0; 3], 1.0).compose(&omni(&[1.0; 4], 1.0)), None);
    }

    #[test]
    fn corrected_geometry() {
        let dd = presets::mobolab();
        let c = Corrections::DiffDrive {
            c_l: 1.02,
            c_r: 0.98,
            e_b: 1.05,
        };
        let g = c.apply_to(&dd);
        assert!((g.wheels[0].radius_m - 0.05 * 1.02).abs() < 1e-15);
        assert!((g.wheels[1].radius_m - 0.05 * 0.98).abs() < 1e-15);
        assert!((g.wheels[1].l_m - 0.20 * 1.05).abs() < 1e-15);
    }
}
