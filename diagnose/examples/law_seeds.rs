//! Temporary experiment: the turn law calibrate fits on simulated free motion, per seed.
use diagnose::calibrate::{calibrate, CalOptions};
use sim::{record, Motion, RandomMotion, RecordConfig, Surface};
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).cloned().unwrap_or("mobolab".into());
    let scrub: f64 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(0.04);
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(format!("{name}.toml"));
    let nominal = formats::robot_file::load(&p).unwrap();
    for base in [50u64, 60, 70, 80, 90, 100, 110, 120] {
        let runs: Vec<_> = (0..3)
            .map(|i| {
                let mut c = RecordConfig {
                    row_rate_hz: 50.0,
                    ..RecordConfig::default()
                };
                c.sim.seed = base + i;
                c.sim.turn_scrub = scrub;
                let motion = Motion::Random(RandomMotion {
                    duration_s: 40.0,
                    ..RandomMotion::default()
                });
                let r = record(&nominal, &[], Surface::flat(), &motion, &c).unwrap();
                (format!("run{i}"), r.recording)
            })
            .collect();
        let c = calibrate(&nominal, &runs, None, &CalOptions::default()).unwrap();
        let law = |c: &diagnose::calibrate::Calibration| {
            c.params
                .iter()
                .find(|p| p.spec.name == "eb_arc" || p.spec.name == "l_arc")
                .map(|p| p.value)
                .unwrap_or(f64::NAN)
        };
        let loo: Vec<f64> = (0..3)
            .map(|k| {
                let sub: Vec<_> = runs
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| *i != k)
                    .map(|(_, r)| r.clone())
                    .collect();
                law(&calibrate(&nominal, &sub, None, &CalOptions::default()).unwrap())
            })
            .collect();
        let m = loo.iter().sum::<f64>() / 3.0;
        let jk = (2.0 / 3.0 * loo.iter().map(|x| (x - m).powi(2)).sum::<f64>()).sqrt();
        println!("  leave-one-out {loo:.5?} jackknife se {jk:.5}");
        let arc = c
            .params
            .iter()
            .find(|p| p.spec.name == "eb_arc" || p.spec.name == "l_arc");
        let eb = c.params.iter().find(|p| p.spec.name == "eb");
        println!(
            "seeds {base}-{}: law {:?} arc_rel {:.5} eb {:?}",
            base + 2,
            arc.map(|a| (a.value, a.sigma)),
            c.turn_law.arc_rel,
            eb.map(|a| (a.value, a.sigma))
        );
    }
}
