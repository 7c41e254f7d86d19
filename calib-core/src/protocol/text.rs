//! Rejection and validation texts built on the board without core's float formatting.

#[allow(unused_imports)]
use super::*;

/// Human-readable reason, truncated to fit.
pub type Reason = String<REASON_LEN>;

/// Formats `v` into a [`Reason`], cutting what does not fit.
pub fn reason(v: &dyn fmt::Display) -> Reason {
    struct Cut<'a>(&'a mut Reason);
    impl fmt::Write for Cut<'_> {
        fn write_str(&mut self, s: &str) -> fmt::Result {
            for c in s.chars() {
                if self.0.push(c).is_err() {
                    return Err(fmt::Error);
                }
            }
            Ok(())
        }
    }
    let mut r = Reason::new();
    let _ = write!(Cut(&mut r), "{v}");
    r
}

/// A number written with up to six decimals without core's float formatting, which costs
/// ~10 KiB of flash on the board (rejection reasons are built there).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        if v.is_nan() {
            return f.write_str("NaN");
        }
        let sign = if v < 0.0 { "-" } else { "" };
        let a = libm::fabs(v);
        if a > 1e12 {
            return write!(f, "{sign}{}", if a.is_infinite() { "inf" } else { ">1e12" });
        }
        let scaled = libm::round(a * 1e6) as u64;
        let (int, mut frac) = (scaled / 1_000_000, scaled % 1_000_000);
        write!(f, "{sign}{int}")?;
        if frac != 0 {
            let mut digits = 6;
            while frac % 10 == 0 {
                frac /= 10;
                digits -= 1;
            }
            write!(f, ".{frac:0digits$}")?;
        }
        Ok(())
    }
}

/// Why corrections were refused, in words (calib-core's own `Display` formats floats
/// with core's formatter; this one does not).
pub struct CorrectionText<'a>(pub &'a CorrectionError);

impl fmt::Display for CorrectionText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let at = |f: &mut fmt::Formatter<'_>, name: &str, index: &Option<usize>| match index {
            Some(i) => write!(f, "{name}[{i}]"),
            None => f.write_str(name),
        };
        match self.0 {
            CorrectionError::NotFinite { name, index } => {
                at(f, name, index)?;
                f.write_str(" must be a finite number")
            }
            CorrectionError::OutOfRange {
                name,
                index,
                value,
                max,
            } => {
                at(f, name, index)?;
                write!(
                    f,
                    " = {} is outside [{}, {}]",
                    Num(*value),
                    Num(crate::correction::FACTOR_MIN),
                    Num(*max)
                )
            }
            CorrectionError::WrongWheelCount { expected, got } => {
                write!(f, "f_lat needs one factor per wheel: {expected}, got {got}")
            }
            CorrectionError::WrongKind { robot } => write!(
                f,
                "these factors do not fit this {} robot (diff_drive takes c_l, c_r, e_b; omni takes f_lat, f_lon)",
                robot.as_str()
            ),
        }
    }
}

/// A robot description error in words, without float formatting.
pub struct RobotText<'a>(pub &'a RobotError);

impl fmt::Display for RobotText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use crate::robot::Problem;
        let e = self.0;
        if let Some((i, name)) = &e.wheel {
            write!(f, "wheel {} ('{}'): ", i + 1, name.as_str())?;
        }
        write!(f, "{}: ", e.field.key())?;
        match e.problem {
            Problem::NotFinite => f.write_str("must be a finite number"),
            Problem::NotPositive(v) => write!(f, "must be positive, got {}", Num(v)),
            Problem::Negative(v) => write!(f, "must not be negative, got {}", Num(v)),
            Problem::RollerParallelToAxle => {
                f.write_str("cos(gamma) = 0: rollers parallel to the axle")
            }
            Problem::DuplicateName => f.write_str("duplicate wheel name"),
            Problem::BadName => f.write_str("must be 1 to 16 characters of [a-z0-9_]"),
            Problem::TooFewWheels(n) => write!(f, "need at least 2 wheels, got {n}"),
            Problem::TooManyWheels(n) => write!(f, "at most {MAX_WHEELS} wheels, got {n}"),
            Problem::SingularJacobian => f.write_str("the wheels cannot resolve (vx, vy, omega)"),
            Problem::LegsMismatch => f.write_str("[legs] only and always for wheeled_legged"),
            Problem::SkidSteerSides { left, right } => write!(
                f,
                "skid_steer needs 2 wheels a side, got {left} left and {right} right"
            ),
            Problem::NotAlongBodyX => f.write_str("a skid-steer wheel rolls along body x"),
            Problem::WrongWheelCount {
                kind,
                expected,
                got,
            } => {
                write!(
                    f,
                    "kind {} needs {expected} wheels, got {got}",
                    kind.as_str()
                )
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
