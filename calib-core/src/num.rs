//! Numbers in messages without core's float formatting.

use core::fmt;

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
