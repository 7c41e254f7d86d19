//! A pose reference that wanders: motion capture whose frame drifts, or a localiser that
//! creeps, leaves a residual that grows over the recording like a random walk whatever
//! the robot does. The white-noise estimate (from consecutive samples) does not hold it,
//! so the ground stage looks outside the noise, and flexible mechanisms bend themselves
//! to the wander. Physics left out of the model is told apart by what its residual
//! follows: a wheel scale adds error in proportion to the displacement, a separation
//! error in proportion to the turning, a tilted floor a steady push. A wander does not.
//!
//! The test works on increments, which keeps a random walk from correlating by chance
//! with quantities that trend (the spurious regression of levels): the pose samples are
//! cut into windows of equal duration, and each window's change of the nominal residual
//! is set against what the robot did in it, three ways, each chi-square under the null
//! hypothesis (a zero-mean random walk plus white noise, alike in every window and
//! direction, independent of the motion) and bounded at its 1 % quantile:
//! - a likelihood ratio of the changes regressed on a constant push (x, y), the
//!   displacement (a scale), the displacement turned by 90 degrees (a heading offset), and
//!   for the heading a constant turn, the rotation and the distance (7 dof);
//! - Koenker's Breusch-Pagan statistic: does the changes' size follow how far the robot
//!   moved and turned (physics errs only when it moves; 4 dof);
//! - the sphericity of the position changes in the robot's frame (2 dof);
//!
//! and no window's change may be an outlier (a jump is an event, not a wander: hub slip,
//! a relocalisation). One recording cannot tell every physics from a wander this way
//! (docs/diagnose.md "Reference wander"): the driver says what the test found beside an
//! `unexplained` verdict and does not change the verdict.

/// Each statistic's size: the probability that a wander exceeds its bound, 1 %.
pub const REFERENCE_DRIFT_FALSE_ALARM: f64 = 0.01;
/// The 0.99 quantile of chi-square with 7 degrees of freedom (tables: 18.475), the
/// likelihood-ratio statistic's bound at [`REFERENCE_DRIFT_FALSE_ALARM`].
pub const CHI2_7_Q99: f64 = 18.475;
/// The 0.99 quantile of chi-square with 4 degrees of freedom (tables: 13.277), the bound
/// of the spread test's statistic (two blocks of two regressors) at
/// [`REFERENCE_DRIFT_FALSE_ALARM`].
pub const CHI2_4_Q99: f64 = 13.277;
/// The 0.99 quantile of chi-square with 2 degrees of freedom (-2 ln 0.01 = 9.210), the
/// bound of the body-frame sphericity statistic at [`REFERENCE_DRIFT_FALSE_ALARM`].
pub const CHI2_2_Q99: f64 = 9.210;
/// Fewest windows the test needs: with fewer, seven regressors leave too few degrees of
/// freedom for the ratio to be chi-square.
pub const MIN_WINDOWS: usize = 16;
/// Most windows: more, shorter windows let the white noise swamp the wander.
pub const MAX_WINDOWS: usize = 40;
/// Shortest window, s: a wander shows over seconds.
pub const MIN_WINDOW_S: f64 = 1.0;

/// What the test measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wander {
    /// Windows used.
    pub windows: usize,
    /// Window length, s.
    pub window_s: f64,
    /// The likelihood-ratio statistic (chi-square with 7 under a wander).
    pub statistic: f64,
    /// The spread statistic: how far the size of the windows' changes follows how much
    /// the robot moved in them (Koenker's studentised Breusch-Pagan, chi-square with 4
    /// under a wander).
    pub spread: f64,
    /// The sphericity statistic of the windows' position changes in the robot's frame
    /// (chi-square with 2 under a wander): a reference wanders alike in every direction
    /// of the room, so alike along and across the robot as it turns; a wheel that slips,
    /// a scale that creeps, a wheel out of round err along the directions the wheels
    /// roll, fixed to the body.
    pub body_shape: f64,
    /// Largest window change of position over its robust scale (a jump when large).
    pub largest_step: f64,
    /// Position wander, m per square root of a second (from the windows' changes).
    pub rate_m_per_sqrt_s: f64,
    /// Heading wander, rad per square root of a second.
    pub rate_rad_per_sqrt_s: f64,
}

impl Wander {
    /// Whether the residual is a wandering reference: the motion explains no more of its
    /// changes than chance would ([`CHI2_7_Q99`]) and no window jumps (the largest change
    /// within the bound that `windows` Rayleigh draws exceed with probability
    /// [`REFERENCE_DRIFT_FALSE_ALARM`]: sigma sqrt(2 ln(windows / alpha))).
    pub fn is_wander(&self) -> bool {
        let jump = (2.0 * (self.windows as f64 / REFERENCE_DRIFT_FALSE_ALARM).ln()).sqrt();
        self.statistic < CHI2_7_Q99
            && self.spread < CHI2_4_Q99
            && self.body_shape < CHI2_2_Q99
            && self.largest_step < jump
    }
}

/// Least squares of `y` on the columns `x` (row-major, `p` per row); the residual sum of
/// squares, or `None` when the columns are degenerate.
fn ols_rss(x: &[f64], y: &[f64], p: usize) -> Option<f64> {
    let n = y.len();
    let a = nalgebra::DMatrix::from_row_slice(n, p, x);
    let b = nalgebra::DVector::from_column_slice(y);
    let ata = a.tr_mul(&a);
    let atb = a.tr_mul(&b);
    let sol = ata.cholesky()?.solve(&atb);
    let r = &a * sol - b;
    Some(r.norm_squared())
}

/// Koenker's studentised Breusch-Pagan statistic: `n R^2` of the squared changes `sq`
/// regressed on a constant and the columns of `z` (row-major, `q` per row); chi-square with
/// `q` degrees of freedom when the changes' spread does not follow `z`. `None` when the
/// columns are degenerate.
fn spread_follows(z: &[f64], sq: &[f64], q: usize) -> Option<f64> {
    let n = sq.len() as f64;
    let mean = sq.iter().sum::<f64>() / n;
    let tss: f64 = sq.iter().map(|v| (v - mean).powi(2)).sum();
    if tss <= 0.0 {
        return None;
    }
    let x: Vec<f64> = z
        .chunks(q)
        .flat_map(|row| std::iter::once(1.0).chain(row.iter().copied()))
        .collect();
    let rss = ols_rss(&x, sq, q + 1)?;
    Some(n * (1.0 - rss / tss).max(0.0))
}

/// The wander test on the ground residual of `e` (pose samples at times `t`, measured
/// poses `x`, `y`, `theta`). `None` when the recording is too short for
/// [`MIN_WINDOWS`] windows of [`MIN_WINDOW_S`], or the motion leaves a regressor empty
/// (a robot that never turned cannot show a separation error, nor hide one).
pub fn test(
    t: &[f64],
    (x, y, theta): (&[f64], &[f64], &[f64]),
    (ex, ey, eth): (&[f64], &[f64], &[f64]),
) -> Option<Wander> {
    let n = t.len();
    if n < 2 * MIN_WINDOWS
        || [x.len(), y.len(), theta.len(), ex.len(), ey.len(), eth.len()]
            .iter()
            .any(|&l| l != n)
    {
        return None;
    }
    let span = t[n - 1] - t[0];
    let windows = ((span / MIN_WINDOW_S).floor() as usize).min(MAX_WINDOWS);
    if windows < MIN_WINDOWS {
        return None;
    }
    let window_s = span / windows as f64;
    // Cuts at the first sample at or after t0 + k w. The jump check takes each change
    // from cut to cut (they add up to the whole, so a jump falls in one of them); the
    // regression from the sample after a cut to the next cut, so that neighbouring
    // windows share no sample and their white noise is independent (the statistic is
    // then chi-square: sharing a sample would make it conservative, its mean 2.8, not 7).
    let mut cuts = vec![0];
    let mut i = 0;
    for k in 1..windows {
        let at = t[0] + k as f64 * window_s;
        while i < n && t[i] < at {
            i += 1;
        }
        if i < n - 1 && i > *cuts.last().unwrap_or(&0) {
            cuts.push(i);
        }
    }
    cuts.push(n - 1);
    let bounds: Vec<(usize, usize)> = cuts
        .windows(2)
        .map(|c| (c[0] + usize::from(c[0] > 0), c[1]))
        .filter(|(a, b)| b > a)
        .collect();
    if bounds.len() < MIN_WINDOWS {
        return None;
    }
    let m = bounds.len();
    let mut motion = Vec::with_capacity(2 * m);
    let mut body = Vec::with_capacity(m);
    let (mut sq_pos, mut sq_head) = (Vec::with_capacity(m), Vec::with_capacity(m));
    let (mut xp, mut yp) = (Vec::with_capacity(8 * m), Vec::with_capacity(2 * m));
    let (mut xh, mut yh) = (Vec::with_capacity(3 * m), Vec::with_capacity(m));
    for &(a, b) in &bounds {
        let (dx, dy) = (x[b] - x[a], y[b] - y[a]);
        let dth = theta[b] - theta[a];
        let ds: f64 = (a..b)
            .map(|k| (x[k + 1] - x[k]).hypot(y[k + 1] - y[k]))
            .sum();
        let (dex, dey) = (ex[b] - ex[a], ey[b] - ey[a]);
        // x: push_x, push_y, scale, heading offset; y likewise.
        xp.extend_from_slice(&[1.0, 0.0, dx, -dy]);
        yp.push(dex);
        xp.extend_from_slice(&[0.0, 1.0, dy, dx]);
        yp.push(dey);
        xh.extend_from_slice(&[1.0, dth, ds]);
        yh.push(eth[b] - eth[a]);
        motion.extend_from_slice(&[ds, dth.abs()]);
        sq_pos.push(dex * dex + dey * dey);
        let (sn, c) = theta[a].sin_cos();
        body.push((c * dex + sn * dey, -sn * dex + c * dey));
        sq_head.push((eth[b] - eth[a]).powi(2));
    }
    let steps: Vec<f64> = cuts
        .windows(2)
        .map(|c| (ex[c[1]] - ex[c[0]]).hypot(ey[c[1]] - ey[c[0]]))
        .collect();
    let rss0 = |v: &[f64]| v.iter().map(|e| e * e).sum::<f64>();
    let (p0, h0) = (rss0(&yp), rss0(&yh));
    let (p1, h1) = (ols_rss(&xp, &yp, 4)?, ols_rss(&xh, &yh, 3)?);
    if !(p0 > 0.0 && h0 > 0.0 && p1 > 0.0 && h1 > 0.0) {
        return None;
    }
    let statistic = (2 * m) as f64 * (p0 / p1).ln() + m as f64 * (h0 / h1).ln();
    // Sphericity of the body-frame changes (zero mean under a wander): the likelihood
    // ratio of a 2 x 2 covariance against a multiple of the identity,
    // m ln((tr S / 2)^2 / det S).
    let (sxx, syy, sxy) = body.iter().fold((0.0, 0.0, 0.0), |(a, b, c), &(u, v)| {
        (a + u * u, b + v * v, c + u * v)
    });
    let det = sxx * syy - sxy * sxy;
    let body_shape = if det > 0.0 {
        m as f64 * ((0.5 * (sxx + syy)).powi(2) / det).ln()
    } else {
        f64::INFINITY
    };
    let spread = spread_follows(&motion, &sq_pos, 2)? + spread_follows(&motion, &sq_head, 2)?;
    // Rayleigh scale from the median change: median = sigma sqrt(2 ln 2).
    let mut sorted = steps;
    sorted.sort_by(f64::total_cmp);
    let k = sorted.len();
    let sigma = sorted[k / 2] / (2.0 * 2f64.ln()).sqrt();
    let largest_step = sorted[k - 1] / sigma.max(1e-300);
    Some(Wander {
        windows: m,
        window_s,
        statistic,
        spread,
        body_shape,
        largest_step,
        rate_m_per_sqrt_s: (p0 / (2 * m) as f64 / window_s).sqrt(),
        rate_rad_per_sqrt_s: (h0 / m as f64 / window_s).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (splitmix64) and Box-Muller normals.
    struct Rng(u64);
    impl Rng {
        fn uniform(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn normal(&mut self) -> f64 {
            let (u, v) = (self.uniform().max(1e-300), self.uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
    }

    /// A wandering drive: 60 s at 50 Hz, speed and turn rate changing every few seconds.
    fn drive(seed: u64) -> (Vec<f64>, [Vec<f64>; 3]) {
        let mut r = Rng(seed);
        let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.0f64);
        let (mut v, mut w) = (0.2f64, 0.0f64);
        let mut out: [Vec<f64>; 3] = Default::default();
        let t: Vec<f64> = (0..3000).map(|k| k as f64 * 0.02).collect();
        for k in 0..t.len() {
            if k % 150 == 0 {
                v = 0.3 * r.uniform();
                w = 1.6 * (r.uniform() - 0.5);
            }
            x += v * th.cos() * 0.02;
            y += v * th.sin() * 0.02;
            th += w * 0.02;
            out[0].push(x);
            out[1].push(y);
            out[2].push(th);
        }
        (t, out)
    }

    /// Residuals: white noise (0.5 mm, 1 mrad) plus a random walk of `rate` per sqrt s
    /// (m; the heading's 1.3 times that in rad), plus `scale` times the displacement from
    /// the start and `turn` times the rotation (physics).
    fn residuals(
        seed: u64,
        pose: &[Vec<f64>; 3],
        rate: f64,
        scale: f64,
        turn: f64,
    ) -> [Vec<f64>; 3] {
        let mut r = Rng(seed ^ 0xABCD);
        let (mut wx, mut wy, mut wh) = (0.0, 0.0, 0.0);
        let step = 0.02f64.sqrt();
        let mut out: [Vec<f64>; 3] = Default::default();
        for ((x, y), th) in pose[0].iter().zip(&pose[1]).zip(&pose[2]) {
            wx += rate * step * r.normal();
            wy += rate * step * r.normal();
            wh += 1.3 * rate * step * r.normal();
            out[0].push(wx + 0.0005 * r.normal() + scale * x);
            out[1].push(wy + 0.0005 * r.normal() + scale * y);
            out[2].push(wh + 0.001 * r.normal() + turn * th);
        }
        out
    }

    fn run(seed: u64, rate: f64, scale: f64, turn: f64) -> Wander {
        let (t, p) = drive(seed);
        let e = residuals(seed, &p, rate, scale, turn);
        test(&t, (&p[0], &p[1], &p[2]), (&e[0], &e[1], &e[2])).unwrap()
    }

    /// Size with white noise alone (no wander): "not a wander" about as often as on a
    /// wander (see below; measured 6 of 200).
    #[test]
    fn white_noise_alone_keeps_the_size() {
        let missed = (0..200)
            .filter(|&s| !run(3000 + s, 0.0, 0.0, 0.0).is_wander())
            .count();
        eprintln!("white noise: {missed} of 200 not a wander");
        assert!(missed <= 13, "{missed}");
    }

    /// Size: on 200 wandering references (0.3 mm/sqrt s, as the habits generator's
    /// drifting capture frame) the test says "not a wander" on about 2 % (two tests at
    /// 1 % each) plus what the chi-square approximation of the likelihood ratio adds
    /// with 40 windows: measured 8 of 200, asserted at most 13 (the binomial 99.9 %
    /// bound at 3 %). A miss here costs nothing new: the verdict is then what it was
    /// without this test. The statistic's mean is near 7, chi-square's with 7 degrees of
    /// freedom (measured 7.6). Power: a 0.3 % wheel scale (27 mm over the drive, 0.6 mm
    /// per window against the wander's 0.8 mm) is taken for a wander at most 3 of 50
    /// times (measured 1); a 0.5 % separation error never (0 of 50). With the spread and
    /// body-frame tests the misses measured 10 of 200 (the bound 13 holds: four 1 %
    /// tests).
    #[test]
    fn a_wander_is_told_from_physics_at_its_stated_rate() {
        let wanders: Vec<Wander> = (0..200).map(|s| run(s, 0.0003, 0.0, 0.0)).collect();
        let missed = wanders.iter().filter(|w| !w.is_wander()).count();
        let mean = wanders.iter().map(|w| w.statistic).sum::<f64>() / 200.0;
        let rate = wanders.iter().map(|w| w.rate_m_per_sqrt_s).sum::<f64>() / 200.0;
        eprintln!(
            "wander: {missed} of 200 not a wander; mean statistic {mean:.2}; rate {rate:.2e}"
        );
        assert!(missed <= 13, "{missed}");
        assert!((5.5..8.5).contains(&mean), "{mean}");
        let scale = (0..50)
            .filter(|&s| run(1000 + s, 0.0003, 0.003, 0.0).is_wander())
            .count();
        let turn = (0..50)
            .filter(|&s| run(2000 + s, 0.0003, 0.0, 0.005).is_wander())
            .count();
        eprintln!("taken for a wander: scale {scale} of 50, separation {turn} of 50");
        assert!(scale <= 3 && turn == 0, "{scale} {turn}");
    }

    /// A jump in one window (a 20 mm relocalisation) is not a wander, whatever the rest.
    #[test]
    fn a_jump_is_not_a_wander() {
        let (t, p) = drive(7);
        let mut e = residuals(7, &p, 0.0003, 0.0, 0.0);
        for v in &mut e[0][1500..] {
            *v += 0.02;
        }
        let w = test(&t, (&p[0], &p[1], &p[2]), (&e[0], &e[1], &e[2])).unwrap();
        eprintln!("{w:?}");
        assert!(!w.is_wander(), "{w:?}");
    }
}
