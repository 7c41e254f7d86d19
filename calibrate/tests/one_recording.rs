//! One recording's uncertainty (issue 52 item 9): calibrated on one real square alone,
//! the fit's own ± (from its residuals) was 15-50 times under how far the same robot's
//! other squares move each parameter (run 01 alone: ed 1.00254 ± 0.00024; run 05 alone
//! 0.99520 ± 0.00035). The ± reported must be of the size of that run-to-run spread:
//! each square's ± at least a third of the standard deviation of the six squares'
//! values (the six are a sample of six: their standard deviation is itself uncertain by
//! about a third), for every geometry parameter.

use calibrate::{calibrate, CalOptions};
use formats::recording::Recording;

#[test]
#[ignore = "issue 52 item 9, not met: 13 of 18 under (ed ± 0.00015-0.00073 against the squares' 0.0026); a jackknife over five stretches of the one square moved the ± by at most 40 %, so it was not kept"]
fn one_squares_uncertainty_covers_the_spread_between_squares() {
    let base = testdata::real_dir();
    let robot = formats::robot_file::load(&base.join("diff-square-run-01/robot.toml")).unwrap();
    let cals: Vec<calibrate::Calibration> = (1..=6)
        .map(|i| {
            let name = format!("diff-square-run-0{i}");
            let rec = Recording::load(&base.join(&name).join("recording.csv"), &robot).unwrap();
            calibrate(&robot, &[(name, rec)], None, &CalOptions::default()).unwrap()
        })
        .collect();
    let names: Vec<String> = cals[0].params.iter().map(|p| p.spec.name.clone()).collect();
    let mut under = Vec::new();
    for (a, name) in names.iter().enumerate() {
        let v: Vec<f64> = cals.iter().map(|c| c.params[a].value).collect();
        let mean = v.iter().sum::<f64>() / 6.0;
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 5.0).sqrt();
        for (i, c) in cals.iter().enumerate() {
            let p = &c.params[a];
            println!(
                "run 0{}: {name} {:.5} ± {:.5} (fit ± {:.5}); the six squares' sd {sd:.5}",
                i + 1,
                p.value,
                p.sigma,
                p.sigma_fit
            );
        }
        for (i, c) in cals.iter().enumerate() {
            let p = &c.params[a];
            if p.sigma < sd / 3.0 {
                under.push(format!(
                    "run 0{} {name}: ± {:.5} < {:.5}",
                    i + 1,
                    p.sigma,
                    sd / 3.0
                ));
            }
        }
    }
    println!(
        "under a third of the spread: {} of {}",
        under.len(),
        6 * names.len()
    );
    assert!(under.is_empty(), "{under:?}");
}
