//! A calibration put on a board in one step (`wheelcal apply`): a robot geometry and the
//! factors that go with it are set together or not at all. Set one by one (`robot set`,
//! then `factors set`), a refusal or a lost link between the two leaves a board holding
//! half a calibration: on the real omni3, the law without its geometry dead-reckons the
//! held-out runs to 131.6 mm where the whole calibration gives 35 mm. So the settings are
//! checked before anything is sent, the geometry goes first, and when the factors are
//! then refused the board's robot is put back; the board is read back at the end.

use crate::client::{Client, ClientError};
use anyhow::{anyhow, bail, Result};
use calib_core::protocol::Params;
use calib_core::Corrections;
use std::io::{Read, Write};

/// What applying needs of a board: its robot parameters and its factors, read and set.
/// [`Client`] in the console; a scripted board in the tests.
pub trait Settings {
    /// The board's parameters (robot, gains, limits, safety).
    fn params(&mut self) -> Result<Params, ClientError>;
    /// Replaces them (the board validates them; idle only).
    fn set_params(&mut self, p: Params) -> Result<(), ClientError>;
    /// The board's active factors.
    fn corrections(&mut self) -> Result<Corrections, ClientError>;
    /// Replaces them (the board validates them against its robot).
    fn set_corrections(&mut self, c: Corrections) -> Result<(), ClientError>;
}

impl<L: Read + Write> Settings for Client<L> {
    fn params(&mut self) -> Result<Params, ClientError> {
        Client::params(self)
    }
    fn set_params(&mut self, p: Params) -> Result<(), ClientError> {
        Client::set_params(self, p)
    }
    fn corrections(&mut self) -> Result<Corrections, ClientError> {
        Client::corrections(self)
    }
    fn set_corrections(&mut self, c: Corrections) -> Result<(), ClientError> {
        Client::set_corrections(self, c)
    }
}

/// What a board is to hold: a new geometry (with the board's other settings kept), or
/// its own (`None`), and factors.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// The parameters to set, or `None` to keep the board's.
    pub params: Option<Params>,
    /// The factors, for the robot the board holds once `params` are set.
    pub corrections: Corrections,
}

impl Target {
    /// Checks what the board would check, before anything is sent: the parameters, and
    /// the factors against the robot they will correct.
    pub fn check(&self, current: &Params) -> Result<()> {
        let robot = match &self.params {
            Some(p) => {
                p.validate()
                    .map_err(|e| anyhow!("the board would refuse this geometry: {e}"))?;
                &p.robot
            }
            None => &current.robot,
        };
        self.corrections.validate(robot).map_err(|e| {
            anyhow!(
                "the board would refuse these factors: {}",
                super::factors::refusal_words(&e)
            )
        })
    }
}

/// Sets `target` on `board`, all or nothing: checks it first ([`Target::check`]), sets
/// the geometry, then the factors; if the factors are refused, the board's previous
/// geometry is set again and the error says so (and, if even that fails, exactly what
/// the board holds). Ends by reading both back: they must be the target's, to the bit.
pub fn apply_settings<B: Settings>(board: &mut B, target: &Target) -> Result<()> {
    let before = board.params()?;
    target.check(&before)?;
    if let Some(p) = &target.params {
        board
            .set_params(p.clone())
            .map_err(|e| anyhow!("the geometry was not set, nothing changed: {e}"))?;
    }
    if let Err(e) = board.set_corrections(target.corrections.clone()) {
        if target.params.is_none() {
            bail!("the factors were not set, nothing changed: {e}");
        }
        return match board.set_params(before) {
            Ok(()) => Err(anyhow!(
                "the factors were refused ({e}); the board's previous geometry was set again, so nothing changed"
            )),
            Err(back) => Err(anyhow!(
                "the factors were refused ({e}) and setting the board's previous geometry again failed too ({back}): the board now holds the new geometry with its old factors (neither saved); set the geometry you want again with `wheelcal robot set`"
            )),
        };
    }
    let (p, c) = (board.params()?, board.corrections()?);
    let want = target.params.as_ref().unwrap_or(&before);
    if &p != want || c != target.corrections {
        bail!("the board reads back other settings than were set (geometry {}, factors {}): nothing was saved", same(&p == want), same(c == target.corrections));
    }
    Ok(())
}

fn same(b: bool) -> &'static str {
    if b {
        "as set"
    } else {
        "differ"
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::geometry::tests::robot;
    use calib_core::protocol::Rejection;

    /// A board that holds settings and refuses the requests it is told to.
    struct Scripted {
        params: Params,
        corrections: Corrections,
        refuse_corrections: bool,
        refuse_params_after: Option<usize>,
        params_sets: usize,
    }

    impl Scripted {
        fn omni3() -> Scripted {
            Scripted {
                params: crate::virtual_board::board_params(&robot("omni3")),
                corrections: Corrections::omni([1.01, 0.99, 1.0].into_iter().collect(), 1.02, 0.0),
                refuse_corrections: false,
                refuse_params_after: None,
                params_sets: 0,
            }
        }
    }

    fn refused() -> ClientError {
        ClientError::Rejected(Rejection::Busy)
    }

    impl Settings for Scripted {
        fn params(&mut self) -> Result<Params, ClientError> {
            Ok(self.params.clone())
        }
        fn set_params(&mut self, p: Params) -> Result<(), ClientError> {
            self.params_sets += 1;
            if self
                .refuse_params_after
                .is_some_and(|n| self.params_sets > n)
            {
                return Err(refused());
            }
            self.params = p;
            Ok(())
        }
        fn corrections(&mut self) -> Result<Corrections, ClientError> {
            Ok(self.corrections.clone())
        }
        fn set_corrections(&mut self, c: Corrections) -> Result<(), ClientError> {
            if self.refuse_corrections {
                return Err(refused());
            }
            self.corrections = c;
            Ok(())
        }
    }

    /// A fitted omni3 geometry (wheels 3 % further out, one turned 1 degree) with factors
    /// of one and a 2 % turn law, on a board holding the nominal robot and other factors.
    fn target(board: &Scripted) -> Target {
        let mut fitted = robot("omni3");
        fitted.wheels.iter_mut().for_each(|w| w.l_m *= 1.03);
        fitted.wheels[1].alpha_rad += 1f64.to_radians();
        Target {
            params: Some(Params {
                robot: fitted,
                ..board.params.clone()
            }),
            corrections: Corrections::omni([1.0; 3].into_iter().collect(), 1.0, 0.02),
        }
    }

    /// Both settings land, to the bit; the board's gains, limits and safety settings are
    /// the target's (which kept the board's).
    #[test]
    fn a_whole_calibration_lands_together() {
        let mut b = Scripted::omni3();
        let t = target(&b);
        apply_settings(&mut b, &t).unwrap();
        assert_eq!(Some(&b.params), t.params.as_ref());
        assert_eq!(b.corrections, t.corrections);
        assert_eq!(b.corrections.l_arc(), 0.02);
    }

    /// Factors refused after the geometry was set: the geometry is set back, so the board
    /// holds exactly what it held before, and the error says so.
    #[test]
    fn refused_factors_put_the_geometry_back() {
        let mut b = Scripted::omni3();
        b.refuse_corrections = true;
        let (p0, c0) = (b.params.clone(), b.corrections.clone());
        let t = target(&b);
        let e = apply_settings(&mut b, &t).unwrap_err().to_string();
        assert!(
            e.contains("previous geometry was set again, so nothing changed"),
            "{e}"
        );
        assert_eq!(b.params, p0);
        assert_eq!(b.corrections, c0);
        assert_eq!(b.params_sets, 2);
    }

    /// If putting the geometry back fails too, the error tells exactly what the board
    /// holds now (the new geometry, the old factors) and how to mend it.
    #[test]
    fn a_failed_restore_says_what_the_board_holds() {
        let mut b = Scripted::omni3();
        b.refuse_corrections = true;
        b.refuse_params_after = Some(1);
        let c0 = b.corrections.clone();
        let t = target(&b);
        let e = apply_settings(&mut b, &t).unwrap_err().to_string();
        assert!(
            e.contains("the board now holds the new geometry with its old factors"),
            "{e}"
        );
        assert_eq!(Some(&b.params), t.params.as_ref());
        assert_eq!(b.corrections, c0);
    }

    /// Settings the board would refuse are refused before anything is sent: a law out of
    /// range (the board takes |l_arc| up to 0.1), factors of another kind of robot, a
    /// wheel of zero radius.
    #[test]
    fn what_the_board_would_refuse_is_not_sent() {
        let bad = |t: Target, says: &str| {
            let mut b = Scripted::omni3();
            let (p0, c0) = (b.params.clone(), b.corrections.clone());
            let e = apply_settings(&mut b, &t).unwrap_err().to_string();
            assert!(e.contains(says), "{e}");
            assert_eq!((b.params_sets, &b.params, &b.corrections), (0, &p0, &c0));
        };
        let b = Scripted::omni3();
        let mut t = target(&b);
        t.corrections = Corrections::omni([1.0; 3].into_iter().collect(), 1.0, 0.2);
        bad(t, "l_arc = 0.2 is outside [-0.1, 0.1]");
        let mut t = target(&b);
        t.corrections = Corrections::diff_drive(1.0, 1.0, 1.0, Default::default());
        bad(t, "the board would refuse these factors");
        let mut t = target(&b);
        if let Some(p) = t.params.as_mut() {
            p.robot.wheels[0].radius_m = 0.0;
        }
        bad(t, "the board would refuse this geometry");
    }
}
