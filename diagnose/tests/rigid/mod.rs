//! Rigid-body helpers the test generators share (`blind/`, `independent/`): each wheel's
//! contact in the body frame, its rolling speed for a body twist, and the least-squares
//! body twist from the wheels' contact speeds. Plain arithmetic written for the tests,
//! not diagnose's kinematics, so the generators stay independent of what they test.

/// One wheel as the generators see it.
pub struct WheelGeo {
    /// Contact position in the body frame.
    pub p: (f64, f64),
    /// Rolling direction in the body frame.
    pub u: (f64, f64),
    /// Rolling radius along `u` (the radius times cos gamma for a mecanum wheel).
    pub r: f64,
}

/// Contact speed of a wheel for body twist (vx, vy, w): u . (v + w x p).
pub fn contact(g: &WheelGeo, v: (f64, f64, f64)) -> f64 {
    g.u.0 * (v.0 - v.2 * g.p.1) + g.u.1 * (v.1 + v.2 * g.p.0)
}

/// Least-squares body twist from the contact speeds of the driven wheels; standard wheels
/// (diff drive, legged) have no free sideways motion, so vy is solved only on omni robots.
pub fn twist_from(geo: &[WheelGeo], s: &[f64], driven: &[bool], omni: bool) -> (f64, f64, f64) {
    let cols: Vec<[f64; 3]> = geo
        .iter()
        .map(|g| [g.u.0, g.u.1, -g.u.0 * g.p.1 + g.u.1 * g.p.0])
        .collect();
    let idx: Vec<usize> = if omni { vec![0, 1, 2] } else { vec![0, 2] };
    let k = idx.len();
    let mut ata = [[0.0; 3]; 3];
    let mut atb = [0.0; 3];
    for (i, c) in cols.iter().enumerate() {
        if !driven[i] {
            continue;
        }
        for a in 0..k {
            atb[a] += c[idx[a]] * s[i];
            for b in 0..k {
                ata[a][b] += c[idx[a]] * c[idx[b]];
            }
        }
    }
    let x = solve(ata, atb, k);
    if omni {
        (x[0], x[1], x[2])
    } else {
        (x[0], 0.0, x[1])
    }
}

/// Gaussian elimination on the leading k x k block.
fn solve(mut a: [[f64; 3]; 3], mut b: [f64; 3], k: usize) -> [f64; 3] {
    for c in 0..k {
        let p = (c..k)
            .max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))
            .unwrap();
        a.swap(c, p);
        b.swap(c, p);
        for r in 0..k {
            if r != c {
                let f = a[r][c] / a[c][c];
                for j in 0..k {
                    a[r][j] -= f * a[c][j];
                }
                b[r] -= f * b[c];
            }
        }
    }
    let mut x = [0.0; 3];
    for c in 0..k {
        x[c] = b[c] / a[c][c];
    }
    x
}

/// An angle wrapped into [-pi, pi).
pub fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}
