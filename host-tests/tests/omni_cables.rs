//! [Redundant omni]'s redundant 4-wheel omni robot over 5 mm cables every 30 mm: ten runs on each of
//! paths 4W-1 and 4W-2, factors F_lat / F_lon from calib_core::omni_cal, ten runs again
//! with the factors in the Jacobian ([Redundant omni] eq. 6), improvement of the mean radial error.

use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::motion::{OmniPath, ProfileLimits, Program};
use calib_core::odometry::{Odometry, Pose};
use calib_core::omni_cal::{self, DrivenWheel, OmniRun, PathRuns};
use calib_core::stats;
use host_tests::{in_frame, robot};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim::{Effect, SimConfig, SimRobot, Surface, WheelInput};
use std::f64::consts::{FRAC_PI_2, TAU};

/// Path length: [Redundant omni] does not give it; 1.5 m over cables every 30 mm is 50 crossings.
const LENGTH_M: f64 = 1.5;
const RUNS: usize = 10;

fn limits() -> ProfileLimits {
    // [Redundant omni]'s robot tops out at 9.75 m/min = 0.1625 m/s.
    ProfileLimits {
        v_max: 0.15,
        a_max: 0.3,
        omega_max: 1.0,
        alpha_max: 2.0,
    }
}

fn path_direction(p: OmniPath) -> f64 {
    match p {
        OmniPath::W1 => 0.0,
        OmniPath::W2 => FRAC_PI_2,
    }
}

/// One run: the wheels a path does not use are switched off (001: "the actuators of
/// wheels 1 and 3 are turned off" on 4W-2); odometry from the driven wheels' encoders
/// along the commanded direction (no sideways motion assumed, as [Redundant omni]'s path model).
/// Returns the error (true minus odometry, path start frame) with the heading error.
fn run(sim: &mut SimRobot, corr: &Corrections, path: OmniPath, start: Pose<f64>) -> OmniRun {
    let r = sim.nominal().clone();
    let kin = Kinematics::<f64>::new(&r, corr).unwrap();
    let d = path_direction(path);
    let (sd, cd) = d.sin_cos();
    let rows: Vec<[f64; 3]> = r.wheels.iter().map(|w| w.rolling_row()).collect();
    let r_eff: Vec<f64> = (0..4)
        .map(|i| r.wheels[i].radius_m * corr.radius_scale(&r, i))
        .collect();
    let driven: Vec<bool> = {
        let mut w = vec![0.0; 4];
        kin.inverse_into(&Twist::new(cd, sd, 0.0), &mut w);
        w.iter().map(|v| v.abs() > 1e-9).collect()
    };
    let mut ext: Vec<_> = (0..4)
        .map(|i| {
            calib_core::encoder::CounterExtender::new(
                calib_core::encoder::CounterWidth::Bits16,
                sim.encoder_raw(i) as u32,
            )
        })
        .collect();
    let rad_per_count = TAU / r.drive.encoder_counts_per_rev;
    let mut odo = Odometry::new(start);
    let mut runner = Program::omni_path(path, LENGTH_M).runner(limits());
    let mut rates = vec![0.0; 4];
    let dt = 1e-3;
    let mut ticks = 0;
    loop {
        let tw = runner.twist_at_tick(dt);
        ticks += tw.is_none() as u32;
        if ticks > 50 {
            break;
        }
        kin.inverse_into(&tw.unwrap_or(Twist::zero()), &mut rates);
        let inputs: Vec<WheelInput> = (0..4)
            .map(|i| {
                if driven[i] {
                    WheelInput::Rate(rates[i])
                } else {
                    WheelInput::Free
                }
            })
            .collect();
        sim.step(dt, &inputs).unwrap();
        // Least squares for (s, omega) from the driven wheels: c_i = a_i s + row_i[2] omega.
        let (mut saa, mut sab, mut sbb, mut sac, mut sbc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for i in 0..4 {
            let dphi = ext[i].update(sim.encoder_raw(i) as u32) as f64 * rad_per_count;
            if !driven[i] {
                continue;
            }
            let c = r_eff[i] * dphi;
            let a = rows[i][0] * cd + rows[i][1] * sd;
            let b = rows[i][2];
            saa += a * a;
            sab += a * b;
            sbb += b * b;
            sac += a * c;
            sbc += b * c;
        }
        let det = saa * sbb - sab * sab;
        let s = (sac * sbb - sab * sbc) / det;
        let om = (saa * sbc - sab * sac) / det;
        odo.update(&Twist::new(s * cd, s * sd, om));
    }
    let t = sim.true_pose();
    let o = odo.pose();
    let (tx, ty) = in_frame(start, d, (t.x, t.y));
    let (ox, oy) = in_frame(start, d, (o.x, o.y));
    OmniRun {
        x_err_m: tx - ox,
        y_err_m: ty - oy,
        theta_err_rad: Some(t.theta - o.theta),
    }
}

fn runs(
    effects: &[Effect],
    corr: &Corrections,
    path: OmniPath,
    seed: u64,
    roughness: f64,
) -> Vec<OmniRun> {
    let r = robot("omni4");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..RUNS)
        .map(|k| {
            // Start anywhere between two cables, heading so the path runs along world +x
            // (across the cables).
            let start = Pose::new(rng.random_range(0.0..0.03), 0.0, -path_direction(path));
            let cfg = SimConfig {
                seed: seed * 100 + k as u64,
                start,
                ..SimConfig::default()
            };
            let (mut faults, surface) =
                sim::Faults::from_effects(&r, effects, Surface::flat()).unwrap();
            faults.travel_noise_m_per_sqrt_m = roughness;
            let mut sim = SimRobot::new(&r, faults, surface, cfg).unwrap();
            run(&mut sim, corr, path, start)
        })
        .collect()
}

fn radial(runs: &[OmniRun]) -> Vec<f64> {
    runs.iter().map(|r| r.x_err_m.hypot(r.y_err_m)).collect()
}

#[test]
fn cable_strip_errors_improve_at_least_80_percent() {
    let r = robot("omni4");
    // The cables cost 1.8 mm of travel each (50 crossings: ~90 mm short, [Redundant omni]'s 91.72 mm
    // mean error); the wheels differ by a few tenths of a percent in effective radius
    // ([Redundant omni]'s F_lat = 1.08 .. 0.96 shows they differ), which curves each path; the floor
    // adds a 0.2 mm/sqrt(m) random walk per wheel.
    let effects = [
        Effect::parse("floor_bumps=spacing_m:0.03,loss_m:0.0018").unwrap(),
        Effect::parse(
            "wheel_diameter_mismatch=radius_scale_w1:1.0015,radius_scale_w2:0.999,radius_scale_w3:0.9985,radius_scale_w4:1.001",
        )
        .unwrap(),
    ];
    let roughness = 2e-4;
    let paths = [OmniPath::W1, OmniPath::W2];
    let before: Vec<Vec<OmniRun>> = paths
        .iter()
        .enumerate()
        .map(|(i, p)| runs(&effects, &Corrections::None, *p, 1 + i as u64, roughness))
        .collect();
    let driven: Vec<Vec<DrivenWheel>> = paths
        .iter()
        .map(|p| {
            let d = path_direction(*p);
            let idx: &[usize] = if *p == OmniPath::W1 { &[0, 2] } else { &[1, 3] };
            idx.iter()
                .map(|&i| DrivenWheel::on_straight_path(i, r.wheels[i].rolling_row(), d, LENGTH_M))
                .collect()
        })
        .collect();
    let path_runs: Vec<PathRuns> = (0..2)
        .map(|i| PathRuns {
            length_m: LENGTH_M,
            direction_rad: path_direction(paths[i]),
            driven: &driven[i],
            runs: &before[i],
            held: &[],
        })
        .collect();
    let cal = omni_cal::calibrate(&path_runs, 4).unwrap();
    let c = cal.correction;
    let corr = Corrections::Omni {
        f_lat: heapless_vec(&c.f_lat[..4]),
        f_lon: c.f_lon,
    };
    corr.validate(&r).unwrap();
    let after: Vec<Vec<OmniRun>> = paths
        .iter()
        .enumerate()
        .map(|(i, p)| runs(&effects, &corr, *p, 11 + i as u64, roughness))
        .collect();

    let all = |v: &[Vec<OmniRun>]| v.iter().flat_map(|r| radial(r)).collect::<Vec<f64>>();
    let (rb, ra) = (all(&before), all(&after));
    let mean_b = stats::mean(&rb).unwrap();
    let mean_a = stats::mean(&ra).unwrap();
    let improvement = stats::improvement_index_percent(mean_b, mean_a).unwrap();
    println!("\n001 omni4 over cables (5 mm every 30 mm, 1.8 mm lost per crossing), L = {LENGTH_M} m, {RUNS} runs per path");
    println!(
        "F_lat = [{:.4}, {:.4}, {:.4}, {:.4}], F_lon = {:.4}",
        c.f_lat[0], c.f_lat[1], c.f_lat[2], c.f_lat[3], c.f_lon
    );
    println!("path  phase   mean radial error   skewness   excess kurtosis");
    for (i, p) in paths.iter().enumerate() {
        for (phase, set) in [("BF", &before[i]), ("AF", &after[i])] {
            let rr = radial(set);
            println!(
                "{:5} {phase}     {:8.2} mm        {:7.3}    {:7.3}",
                p.as_str(),
                stats::mean(&rr).unwrap() * 1e3,
                stats::skewness(&rr).unwrap(),
                stats::excess_kurtosis(&rr).unwrap()
            );
        }
    }
    println!(
        "both  BF {:.2} mm -> AF {:.2} mm: improvement {improvement:.1} % ([Redundant omni] Table II: 91.72 -> 15.43 mm, 80 %)",
        mean_b * 1e3,
        mean_a * 1e3
    );
    // The cables alone shorten 1.5 m by 50 x 1.8 mm = 90 mm: the before error must be of
    // that size (90 mm plus the curvature's lateral part, minus nothing).
    assert!(mean_b > 0.085 && mean_b < 0.2, "before {mean_b}");
    // F_lon makes up the lost 6 % of travel: 1 / (1 - 0.06) = 1.064, within the scatter of
    // the crossing count (+-1 of 50: 2 %) and the radius mix (0.15 %).
    assert!((c.f_lon - 1.064).abs() < 0.01, "f_lon {}", c.f_lon);
    // [Redundant omni] reports 80 %; the remaining error here is the non-systematic part only.
    assert!(improvement >= 80.0, "improvement {improvement} %");
}

fn heapless_vec(v: &[f64]) -> heapless::Vec<f64, 8> {
    heapless::Vec::from_slice(v).unwrap()
}
