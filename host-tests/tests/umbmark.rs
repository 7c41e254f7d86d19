//! UMBmark ([Measuring errors] sec. 6.2, Borenstein & Feng 1996) on [Measuring errors]'s three stepper differential
//! drives: seeded wheel-diameter and wheelbase errors plus random floor roughness, five cw
//! and five ccw 4 m squares driven by calib-core's motion program with its odometry,
//! factors from calib_core::umbmark, then five and five again with the factors applied.

use calib_core::correction::Corrections;
use calib_core::motion::{Direction, ProfileLimits, Program};
use calib_core::odometry::Pose;
use calib_core::umbmark::{self, Run};
use host_tests::{in_frame, robot, Board};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim::{Faults, SimConfig, SimRobot, Surface};

const SIDE_M: f64 = 4.0;
const RUNS: usize = 5;

fn limits() -> ProfileLimits {
    ProfileLimits {
        v_max: 0.4,
        a_max: 0.4,
        omega_max: 1.0,
        alpha_max: 2.0,
    }
}

/// Five runs in each direction; error = true end minus odometry end, start frame.
fn runs(
    r: &calib_core::Robot,
    faults: &Faults,
    corr: &Corrections,
    seed: u64,
) -> (Vec<Run>, Vec<Run>) {
    let mut out = (Vec::new(), Vec::new());
    for (d, dir) in [Direction::Cw, Direction::Ccw].into_iter().enumerate() {
        for k in 0..RUNS {
            let start = Pose::new(0.0, 0.0, 0.0);
            let cfg = SimConfig {
                seed: seed * 1000 + (d * RUNS + k) as u64,
                start,
                ..SimConfig::default()
            };
            let mut sim = SimRobot::new(r, faults.clone(), Surface::flat(), cfg).unwrap();
            let mut board = Board::new(&sim, corr, start);
            board.run(&mut sim, &Program::umbmark_square(SIDE_M, dir), limits());
            let t = sim.true_pose();
            let o = board.odometry.pose();
            let (tx, ty) = in_frame(start, 0.0, (t.x, t.y));
            let (ox, oy) = in_frame(start, 0.0, (o.x, o.y));
            let run = Run {
                x_err_m: tx - ox,
                y_err_m: ty - oy,
            };
            if dir == Direction::Cw {
                out.0.push(run);
            } else {
                out.1.push(run);
            }
        }
    }
    out
}

fn e_max_sys(cw: &[Run], ccw: &[Run]) -> f64 {
    umbmark::e_max_sys(
        umbmark::centroid(cw).unwrap(),
        umbmark::centroid(ccw).unwrap(),
    )
}

/// (robot, E_d, E_b, E_max,sys before, after closed form, after exact fit), metres.
type Row = (&'static str, f64, f64, f64, f64, f64);

fn table(ed_range: (f64, f64), eb_range: (f64, f64), seed: u64) -> Vec<Row> {
    let mut table = Vec::new();
    for (i, name) in ["robotest", "mobolab", "sweeper"].into_iter().enumerate() {
        let r = robot(name);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + i as u64);
        let ed: f64 = rng.random_range(ed_range.0..ed_range.1);
        let eb: f64 = rng.random_range(eb_range.0..eb_range.1);
        let mut faults = Faults::none(2);
        // Borenstein's E_d = D_R / D_L with the mean diameter nominal (left is wheel 0).
        let (c_l, c_r) = calib_core::umbmark::wheel_factors(ed);
        faults.radius_scale = vec![c_l, c_r];
        faults.wheelbase_scale = eb;
        // Non-systematic: floor roughness, a 0.2 mm/sqrt(m) random walk of each wheel's
        // travel (about 0.8 mm per wheel over a 16 m square).
        faults.travel_noise_m_per_sqrt_m = 2e-4;
        let b = 2.0 * r.half_wheelbase_m();

        let (cw, ccw) = runs(&r, &faults, &Corrections::None, seed * 10 + i as u64);
        let before = e_max_sys(&cw, &ccw);
        let cf = umbmark::closed_form(&cw, &ccw, SIDE_M, b).unwrap();
        let fit = umbmark::exact_fit(&cw, &ccw, SIDE_M, b).unwrap();
        // The exact fit recovers the seeded errors: E_d to 1e-3 (1e-3 curves a 4 m leg by
        // 4 m x 1e-3 x 4 m / (2 b) ~ 2-3 cm, far above the noise of a 5-run centroid,
        // ~1 mm here), E_b to 2e-3.
        assert!(
            (fit.result.ed - ed).abs() < 1e-3,
            "{name}: ed {} vs {ed}",
            fit.result.ed
        );
        assert!(
            (fit.result.eb - eb).abs() < 2e-3,
            "{name}: eb {} vs {eb}",
            fit.result.eb
        );

        let mut after = Vec::new();
        for res in [&cf, &fit.result] {
            let corr = Corrections::DiffDrive {
                c_l: res.c_l,
                c_r: res.c_r,
                e_b: res.eb,
            };
            let (cw2, ccw2) = runs(&r, &faults, &corr, seed * 10 + 5 + i as u64);
            after.push(e_max_sys(&cw2, &ccw2));
        }
        table.push((name, ed, eb, before, after[0], after[1]));
    }
    println!("\nUMBmark, n = {RUNS} cw + {RUNS} ccw, L = {SIDE_M} m, E_d in {ed_range:?}, E_b in {eb_range:?}");
    println!("robot     E_d     E_b     E_max,sys before  after (closed form)  after (exact fit)  improvement (cf / exact)");
    for (name, ed, eb, before, cf, ex) in &table {
        println!(
            "{name:9} {ed:.4}  {eb:.4}  {:10.2} mm  {:10.2} mm        {:10.2} mm      {:6.1}x / {:6.1}x",
            before * 1e3,
            cf * 1e3,
            ex * 1e3,
            before / cf,
            before / ex
        );
    }
    table
}

#[test]
fn umbmark_improves_e_max_sys_tenfold_with_large_errors() {
    // E_d 1.003-1.01, E_b 1.02-1.05: end errors of a metre or more.
    for (name, _, eb, before, cf, ex) in table((1.003, 1.01), (1.02, 1.05), 100) {
        // [Measuring errors] Table 1 reports 5x to 11x on real robots; here the systematic part is fully
        // modelled, so the exact fit must do at least 10x. Borenstein's closed form is
        // first order in alpha = pi/2 (1 - 1/E_b): with E_b = 1.04, alpha = 0.06 rad and
        // the neglected second-order terms (alpha^2 ~ 4e-3 of 16 m) leave decimetres, so
        // it is only asked for 3x here (it gets 10x on 000-sized errors, next test).
        assert!(before / ex >= 10.0, "{name}: {before} -> {ex}");
        assert!(before / cf >= 3.0, "{name} (E_b {eb}): {before} -> {cf}");
    }
}

#[test]
fn umbmark_improves_e_max_sys_tenfold_with_000_sized_errors() {
    // E_d 1.0005-1.0015, E_b 1.002-1.005: E_max,sys of order 0.1-0.3 m, as [Measuring errors] Table 1
    // (97 mm before); both estimates must improve it at least 10x.
    for (name, _, _, before, cf, ex) in table((1.0005, 1.0015), (1.002, 1.005), 200) {
        assert!(before / ex >= 10.0, "{name}: {before} -> {ex}");
        assert!(before / cf >= 10.0, "{name}: {before} -> {cf}");
    }
}
