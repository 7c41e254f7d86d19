//! What the caller chooses ([`CalOptions`]; [`CvBy`]: how cross-validation groups the
//! recordings), and the settings the driver derives from them ([`Cfg`]: objective, loss,
//! lever arm, known turn law) that every problem of one calibration is given alike.

use crate::params::{GeomKind, ParamSpec};
use crate::problem::Problem;
use crate::series::PART_SEP;
use crate::turn_law::TurnLaw;

/// Options of [`calibrate`](crate::calibrate).
#[derive(Debug, Clone, Default)]
pub struct CalOptions {
    /// Run leave-one-out cross-validation (when there are at least 2 recordings): the
    /// same as `cv: Some(CvBy::Run)`.
    pub leave_one_out: bool,
    /// Also fit where motion capture tracks on the body (omni robots).
    pub marker_offset: bool,
    /// Fit each recording's start pose, time offset and clock ratio (for recordings whose
    /// frame is not the robot's start frame); else dead-reckon from the first pose.
    pub free_start: bool,
    /// Huber's loss instead of least squares (dead-reckoning objective). Off by default:
    /// on the held-out proxy it transferred worse (geometric mean ratio 1.041 against
    /// 0.987 with squared loss, events kept out either way).
    pub robust: bool,
    /// Cross-validation: hold out whole runs, sessions or kinds of motion.
    pub cv: Option<CvBy>,
    /// Lever arm (m) of the heading residuals in the dead-reckoning objective (default
    /// [`DR_HEADING_LEVER_M`](crate::DR_HEADING_LEVER_M)).
    pub heading_lever_m: Option<f64>,
    /// A differential drive's known turn law, eb_arc / eb (the effective separation on
    /// arcs against a turn in place, [`calib_core::kinematics::turn_law_share`]), from an
    /// earlier calibration on runs with arcs: held fixed while the geometry is fitted.
    /// Squares turn in place and cannot find it (measured: it transfers across days on
    /// the OptiOdom robot).
    pub turn_law: Option<f64>,
    /// A differential drive's known speed law, speed_rel per m/s (each side's wheels roll
    /// 1 + speed_rel |v| times what their radius says), from an earlier calibration on
    /// runs at several speeds: held fixed while the geometry is fitted. Squares run at
    /// one cruise speed and cannot tell it from the wheel size.
    pub speed_law: Option<f64>,
    /// Recordings of the motion the robot file and ROS 2 are for (`--e-b-for`: a log of
    /// everyday driving; only the encoders are read). With a turn law, which neither can
    /// apply, their one E_b is the constant whose dead reckoning of this motion stays
    /// closest to the law's; without, E_b is at the fitted recordings' mean turn.
    pub e_b_for: Vec<(String, formats::recording::Recording)>,
    /// Parameters held at the robot file's values: measured some other way (a wheel's
    /// diameter with calipers), or a smaller model to compare on held-out runs.
    /// `--hold scale|ed|eb` on a differential drive or skid-steer robot ([`HOLDABLE`]);
    /// `--hold radius|distance|angle|roller|centre` on an omni robot
    /// ([`OMNI_HOLDABLE`]), each a family of its model ladder's parameters.
    pub hold: Vec<String>,
}

/// The parameters `--hold` may name, in a differential drive's or skid-steer robot's
/// [`param_specs`](crate::param_specs) order.
pub const HOLDABLE: [&str; 3] = ["scale", "ed", "eb"];

/// The families of an omni robot's ladder ([`ladder`](crate::ladder)) that
/// `--hold` may name: the wheels' size (common scale and per-wheel radii), their
/// distances from the centre (common and per wheel), their mounting angles, a mecanum
/// robot's roller angle, and the wheels' centre.
pub const OMNI_HOLDABLE: [&str; 5] = ["radius", "distance", "angle", "roller", "centre"];

/// Which of [`HOLDABLE`] and [`OMNI_HOLDABLE`] are held (bit i: the i-th name of the two
/// lists in turn).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct Held(u8);

impl Held {
    /// Every name, bit by bit.
    fn all() -> impl Iterator<Item = &'static str> {
        HOLDABLE.into_iter().chain(OMNI_HOLDABLE)
    }

    /// The families named in `hold` (names of neither list are checked before).
    pub(super) fn of(hold: &[String]) -> Held {
        Held(
            Self::all()
                .enumerate()
                .filter(|(_, n)| hold.iter().any(|h| h == n))
                .fold(0, |m, (i, _)| m | 1 << i),
        )
    }

    /// Whether anything is held.
    pub(super) fn any(self) -> bool {
        self.0 != 0
    }

    /// The held families' names.
    pub(super) fn names(self) -> Vec<&'static str> {
        Self::all()
            .enumerate()
            .filter(|(i, _)| self.0 & 1 << i != 0)
            .map(|(_, n)| n)
            .collect()
    }

    /// Whether `s` belongs to a held family. A common scale is a differential drive's
    /// `scale` and an omni robot's `radius`; a common distance its `eb` and `distance`
    /// (the names are checked against the robot's kind before).
    pub(super) fn holds(self, s: &ParamSpec) -> bool {
        let families: &[&str] = match s.kind {
            GeomKind::Scale => &["scale", "radius"],
            GeomKind::Ed => &["ed"],
            GeomKind::Eb => &["eb", "distance"],
            GeomKind::Radius(_) => &["radius"],
            GeomKind::L(_) => &["distance"],
            GeomKind::Alpha(_) => &["angle"],
            GeomKind::Gamma => &["roller"],
            GeomKind::CentreX | GeomKind::CentreY => &["centre"],
            _ => &[],
        };
        self.names().iter().any(|n| families.contains(n))
    }
}

/// How cross-validation groups recordings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CvBy {
    /// Each recording alone.
    Run,
    /// Recordings of one session (the name without its `-run-NN` suffix).
    Session,
    /// Recordings of one kind of motion (the name's second dash field:
    /// `<robot>-<path>-<session>-run-NN`, e.g. square, circular, ivanjko).
    PathKind,
}

impl CvBy {
    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            CvBy::Run => "run",
            CvBy::Session => "session",
            CvBy::PathKind => "path-kind",
        }
    }

    /// Parses `run`, `session` or `path-kind`.
    pub fn parse(s: &str) -> Option<CvBy> {
        match s {
            "run" => Some(CvBy::Run),
            "session" => Some(CvBy::Session),
            "path-kind" | "path" => Some(CvBy::PathKind),
            _ => None,
        }
    }

    /// The group of a recording named `name` (a run folder's name, or a file name).
    pub fn group(self, name: &str) -> String {
        // The parts of a recording split at a pose jump stay together.
        let name = name.split(PART_SEP).next().unwrap_or(name);
        let base = name.trim_end_matches(".csv");
        match self {
            CvBy::Run => base.to_string(),
            CvBy::Session => match base.rfind("-run-") {
                Some(i) => base[..i].to_string(),
                None => base.to_string(),
            },
            CvBy::PathKind => base.split('-').nth(1).unwrap_or(base).to_string(),
        }
    }
}

#[derive(Debug, Clone, Copy)]
pub(super) struct Cfg {
    pub(super) free_start: bool,
    pub(super) huber: Option<f64>,
    pub(super) dr_lever: f64,
    /// Known laws ([`CalOptions::turn_law`], [`CalOptions::speed_law`]), when given.
    pub(super) known_law: Option<TurnLaw>,
    /// The families held ([`CalOptions::hold`]).
    pub(super) held: Held,
}

impl Cfg {
    /// The known laws, zero when none is given.
    pub(super) fn law(&self) -> TurnLaw {
        self.known_law.unwrap_or_default()
    }

    /// `specs` less the parameters held.
    pub(super) fn unheld(&self, specs: Vec<ParamSpec>) -> Vec<ParamSpec> {
        specs.into_iter().filter(|s| !self.held.holds(s)).collect()
    }

    /// An omni robot's model ladder less the families held: a rung that lost parameters
    /// is named for the held families it had, an empty rung and a rung the same as a
    /// simpler one go.
    pub(super) fn unheld_ladder(
        &self,
        rungs: Vec<(&'static str, Vec<ParamSpec>)>,
    ) -> Vec<(String, Vec<ParamSpec>)> {
        let mut out: Vec<(String, Vec<ParamSpec>)> = Vec::new();
        for (name, specs) in rungs {
            // The held families this rung has: what its name must say it lost.
            let lost: Vec<&str> = self
                .held
                .names()
                .into_iter()
                .filter(|&f| specs.iter().any(|s| Held::of(&[f.into()]).holds(s)))
                .collect();
            let kept = self.unheld(specs);
            let same = |o: &(String, Vec<ParamSpec>)| {
                o.1.iter().map(|s| &s.name).eq(kept.iter().map(|s| &s.name))
            };
            if kept.is_empty() || out.iter().any(same) {
                continue;
            }
            let name = if lost.is_empty() {
                name.to_string()
            } else {
                format!("{name}, {} held", lost.join(" and "))
            };
            out.push((name, kept));
        }
        out
    }

    pub(super) fn apply(&self, p: &mut Problem) {
        p.free_start = self.free_start;
        p.huber = self.huber;
        p.dr_lever = self.dr_lever;
        p.known_law = self.law();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ladder;
    use crate::synth::robot;

    /// The omni3's ladder with the distance and the centre held: the common-scale rung
    /// keeps its name, the rung that had only the distance names the distance alone, the
    /// centre rung (the same as the per-wheel radii rung once both go) goes, and every
    /// remaining rung has one parameter fewer per held family it had.
    #[test]
    fn a_held_ladder_names_what_each_rung_lost() {
        let omni3 = robot("omni3");
        let cfg = Cfg {
            free_start: false,
            huber: None,
            dr_lever: 0.1,
            known_law: None,
            held: Held::of(&["distance".into(), "centre".into()]),
        };
        let full = ladder(&omni3, false);
        let held = cfg.unheld_ladder(full.clone());
        let got: Vec<(&str, usize)> = held.iter().map(|(n, s)| (n.as_str(), s.len())).collect();
        assert_eq!(
            got,
            [
                ("common scale", 1),
                (
                    "per-wheel radii and a common wheel distance, distance held",
                    3
                ),
                ("per-wheel radii, angles and distances, distance held", 6),
            ],
            "from {:?}",
            full.iter().map(|r| (r.0, r.1.len())).collect::<Vec<_>>()
        );
    }
}
