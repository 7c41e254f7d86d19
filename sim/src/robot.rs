//! [`SimRobot`]: the stepped simulation a virtual board drives.
//!
//! The board's view: `step(dt, &inputs)` once per control tick, then read
//! [`SimRobot::encoder_raw`] (16-bit wrapping counters), [`SimRobot::imu_yaw_rate`] and, when
//! a camera frame arrived during the tick, [`SimRobot::vision`]. The truth
//! ([`SimRobot::true_pose`]) is for tests and recordings only.

use crate::actuator::{Actuator, WheelInput};
use crate::body::{actual_robot, place_legs, Geometry};
use crate::effects::{Effect, Faults};
use crate::encoder::Encoder;
use crate::error::check_range;
use crate::ground::{Ground, GroundParams};
use crate::motor::DcParams;
use crate::sensors::{ImuConfig, VisionConfig};
use crate::surface::Surface;
use crate::SimError;
use calib_core::kinematics::Twist;
use calib_core::odometry::Pose;
use calib_core::robot::{Robot, RobotKind};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Where the encoders sit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EncoderMount {
    /// On the wheel axle: sees the wheel after the gear's backlash.
    #[default]
    Wheel,
    /// On the motor shaft: sees the motor, not the play between motor and wheel.
    Motor,
}

/// Everything about a run that is not the robot, its faults or the floor.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// Seeds every random stream (roughness, sensors, counter start values).
    pub seed: u64,
    /// Where the encoders sit (wheel or motor shaft).
    pub encoder_mount: EncoderMount,
    /// DC motor constants; `None` = [`DcParams::typical`] with a 20 rad/s no-load wheel
    /// speed.
    pub dc: Option<DcParams>,
    /// Position sensor (camera) settings.
    pub vision: VisionConfig,
    /// Gyroscope settings.
    pub imu: ImuConfig,
    /// Start pose in the world frame (m, m, rad).
    pub start: Pose<f64>,
    /// Initial leg angles (wheeled-legged robots), rad; pi/2 = vertical.
    pub leg_front_rad: f64,
    /// Initial rear leg angle (wheeled-legged robots), rad; pi/2 = vertical.
    pub leg_rear_rad: f64,
    /// Start the 16-bit counters at random values (as hardware does) rather than 0.
    pub random_counter_start: bool,
    /// Tyre-ground friction of a skid-steer robot (other kinds ignore it).
    pub tyre: crate::skid::Tyre,
    /// Growth of the effective separation from a turn in place to a wide arc (wide
    /// tyres): E_b(rho) = E_b (1 + turn_scrub (1 - rho^2)), rho = |v_r - v_l| /
    /// (|v_r| + |v_l|) (`calib_core::kinematics::turn_law_share`). On an omni robot the
    /// wheels' distance from the centre grows likewise, rho = |omega| L / |v| of the twist
    /// (`calib_core::kinematics::turn_ratio`). 0: the distance does not depend on the
    /// turn.
    pub turn_scrub: f64,
    /// Growth of each driven wheel's effective rolling radius with its rolling speed, per
    /// m/s: a wheel turning at v rolls (1 + speed_scale |v|) times its radius (tyres that
    /// deform or slip more the faster they turn), v its rolling speed smoothed over 0.1 s
    /// (a stepper moves in whole steps). 0: the size does not depend on speed.
    pub speed_scale: f64,
    /// Rolling speed (m/s) beyond which [`SimConfig::speed_scale`]'s growth stops: a
    /// wheel turning faster rolls as one at this speed (a tyre whose deformation
    /// saturates). Infinite: the growth never stops.
    pub speed_scale_top_m_s: f64,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            seed: 0,
            encoder_mount: EncoderMount::Wheel,
            dc: None,
            vision: VisionConfig::default(),
            imu: ImuConfig::default(),
            start: Pose::new(0.0, 0.0, 0.0),
            leg_front_rad: std::f64::consts::FRAC_PI_2,
            leg_rear_rad: std::f64::consts::FRAC_PI_2,
            random_counter_start: true,
            tyre: crate::skid::Tyre::default(),
            turn_scrub: 0.0,
            speed_scale: 0.0,
            speed_scale_top_m_s: f64::INFINITY,
        }
    }
}

/// A simulated robot.
#[derive(Debug, Clone)]
pub struct SimRobot {
    nominal: Robot,
    /// Faulty geometry with legs at their current angles.
    actual: Robot,
    geom: Geometry,
    faults: Faults,
    surface: Surface,
    cfg: SimConfig,
    ground_params: GroundParams,
    actuators: Vec<Actuator>,
    wheel_angle: Vec<f64>,
    encoders: Vec<Encoder>,
    ground: Ground,
    legs: (f64, f64),
    t: f64,
    dphi: Vec<f64>,
    rng_ground: ChaCha8Rng,
    /// The seed `rng_ground` started from (each trial of a virtual board restarts from it).
    ground_seed: u64,
    rng_vision: ChaCha8Rng,
    rng_imu: ChaCha8Rng,
    next_vision_t: f64,
    vision: Option<(f64, Pose<f64>)>,
    vision_new: bool,
}

/// Share of the weight on the driven wheels: by moment balance for wheeled-legged robots
/// (front pair carries `front_load_share`), 1 otherwise (castors taken as unloaded).
pub fn driven_load_share(robot: &Robot, leg_front: f64, leg_rear: f64) -> f64 {
    match (robot.kind, robot.legs) {
        (RobotKind::WheeledLegged, Some(legs)) => {
            let front = legs.front_load_share(leg_front, leg_rear).unwrap_or(0.5);
            let is_front = |w: &calib_core::robot::Wheel| w.position().0 >= 0.0;
            let nf = robot.wheels.iter().filter(|w| is_front(w)).count().max(1) as f64;
            let nr = robot.wheels.iter().filter(|w| !is_front(w)).count().max(1) as f64;
            robot
                .wheels
                .iter()
                .filter(|w| w.driven)
                .map(|w| {
                    if is_front(w) {
                        front / nf
                    } else {
                        (1.0 - front) / nr
                    }
                })
                .sum()
        }
        _ => 1.0,
    }
}

impl SimRobot {
    /// A simulation of `nominal` with `faults` on `surface`.
    pub fn new(
        nominal: &Robot,
        faults: Faults,
        surface: Surface,
        cfg: SimConfig,
    ) -> Result<Self, SimError> {
        let n = nominal.wheel_count();
        faults.validate(n)?;
        cfg.vision.validate()?;
        cfg.imu.validate()?;
        cfg.tyre.validate()?;
        crate::error::check_range("turn_scrub", cfg.turn_scrub, -0.5, 0.5)?;
        // The scrub acts on robots that turn by rolling: through the sides of a
        // differential drive, through the twist of an omni robot.
        if cfg.turn_scrub != 0.0
            && !matches!(
                nominal.kind,
                calib_core::RobotKind::DiffDrive | calib_core::RobotKind::Omni
            )
        {
            return Err(SimError::Config {
                field: "turn_scrub",
                message: format!(
                    "widens the wheels' effective separation (a differential drive's) or distance from the centre (an omni robot's) on arcs; robot '{}' is {}",
                    nominal.name,
                    nominal.kind.as_str()
                ),
            });
        }
        crate::error::check_range("speed_scale", cfg.speed_scale, -0.5, 0.5)?;
        if cfg.speed_scale_top_m_s.is_nan() || cfg.speed_scale_top_m_s < 0.0 {
            crate::error::check_range(
                "speed_scale_top_m_s",
                cfg.speed_scale_top_m_s,
                0.0,
                f64::MAX,
            )?;
        }
        for (field, v) in [
            ("start.x", cfg.start.x),
            ("start.y", cfg.start.y),
            ("start.theta", cfg.start.theta),
        ] {
            check_range(field, v, -1e6, 1e6)?;
        }
        check_range("leg_front_rad", cfg.leg_front_rad, -10.0, 10.0)?;
        check_range("leg_rear_rad", cfg.leg_rear_rad, -10.0, 10.0)?;
        if let Some(c) = &surface.cables {
            check_range("surface.cables.spacing_m", c.spacing_m, 1e-6, 1e6)?;
            check_range("surface.cables.loss_m", c.loss_m, 0.0, c.spacing_m)?;
        }
        for p in &surface.patches {
            check_range("surface.patches.mu_scale", p.mu_scale, 0.0, 100.0)?;
        }
        let gear = nominal.drive.gear_ratio;
        let dc = cfg.dc.unwrap_or_else(|| DcParams::typical(gear, 20.0));
        for v in [dc.v_supply, dc.k_t, dc.k_e, dc.r_ohm, dc.inertia] {
            check_range("dc (v_supply, k_t, k_e, r_ohm, inertia)", v, 1e-12, 1e6)?;
        }
        check_range("dc.viscous", dc.viscous, 0.0, 1e6)?;
        check_range("dc.coulomb", dc.coulomb, 0.0, 1e6)?;
        let mut seeder = ChaCha8Rng::seed_from_u64(cfg.seed);
        let ground_seed: u64 = seeder.random();
        let rng_ground = ChaCha8Rng::seed_from_u64(ground_seed);
        let rng_vision = ChaCha8Rng::seed_from_u64(seeder.random());
        let rng_imu = ChaCha8Rng::seed_from_u64(seeder.random());
        let actuators = (0..n)
            .map(|i| {
                Actuator::new(
                    &nominal.drive,
                    dc,
                    faults.deadband_rad_s,
                    faults.tau_s,
                    faults.backlash_rad,
                    faults.max_accel_rad_s2,
                )
                .with_mechanisms(&faults.mech, cfg.seed ^ (i as u64 + 1).wrapping_mul(0x9e37))
            })
            .collect();
        let encoders = (0..n)
            .map(|_| {
                let off = if cfg.random_counter_start {
                    seeder.random::<u16>()
                } else {
                    0
                };
                Encoder::new(nominal.drive.encoder_counts_per_rev, off)
            })
            .collect();
        let legs = (cfg.leg_front_rad, cfg.leg_rear_rad);
        let actual = Self::actual_for(nominal, &faults, legs);
        let geom = Geometry::new(&actual)?;
        let ground_params = GroundParams {
            mu: faults.mu,
            driven_load_share: faults
                .driven_load_share
                .unwrap_or_else(|| driven_load_share(nominal, legs.0, legs.1)),
            side_slip_s: faults.side_slip_s,
            tyre: cfg.tyre,
            turn_scrub: cfg.turn_scrub,
            speed_scale: cfg.speed_scale,
            speed_scale_top_m_s: cfg.speed_scale_top_m_s,
            travel_noise_m_per_sqrt_m: faults.travel_noise_m_per_sqrt_m,
            mech: faults.mech,
        };
        Ok(SimRobot {
            nominal: nominal.clone(),
            actual,
            geom,
            ground: Ground::new(cfg.start, n),
            faults,
            surface,
            ground_params,
            actuators,
            wheel_angle: vec![0.0; n],
            encoders,
            legs,
            t: 0.0,
            dphi: vec![0.0; n],
            rng_ground,
            ground_seed,
            rng_vision,
            rng_imu,
            next_vision_t: 0.0,
            vision: None,
            vision_new: false,
            cfg,
        })
    }

    /// A simulation with the catalogue's effects (see [`Faults::from_effects`]).
    pub fn with_effects(
        nominal: &Robot,
        effects: &[Effect],
        surface: Surface,
        cfg: SimConfig,
    ) -> Result<Self, SimError> {
        let (faults, surface) = Faults::from_effects(nominal, effects, surface)?;
        SimRobot::new(nominal, faults, surface, cfg)
    }

    fn actual_for(nominal: &Robot, faults: &Faults, legs: (f64, f64)) -> Robot {
        let placed = place_legs(nominal, legs.0, legs.1);
        actual_robot(&placed, &faults.radius_scale, faults.wheelbase_scale)
    }

    /// Sets the leg angles (wheeled-legged robots; ignored otherwise): moves the contact
    /// points and the load shares from the next tick on.
    pub fn set_legs(&mut self, leg_front_rad: f64, leg_rear_rad: f64) -> Result<(), SimError> {
        check_range("leg_front_rad", leg_front_rad, -10.0, 10.0)?;
        check_range("leg_rear_rad", leg_rear_rad, -10.0, 10.0)?;
        if self.nominal.kind != RobotKind::WheeledLegged
            || (leg_front_rad, leg_rear_rad) == self.legs
        {
            return Ok(());
        }
        let legs = (leg_front_rad, leg_rear_rad);
        let actual = Self::actual_for(&self.nominal, &self.faults, legs);
        self.geom = Geometry::with_motors_off(&actual, self.geom.off_mask)?;
        self.actual = actual;
        self.legs = legs;
        if self.faults.driven_load_share.is_none() {
            self.ground_params.driven_load_share = driven_load_share(&self.nominal, legs.0, legs.1);
        }
        Ok(())
    }

    /// Advances one control tick of `dt` seconds with one input per wheel (free wheels'
    /// inputs are ignored).
    pub fn step(&mut self, dt: f64, inputs: &[WheelInput]) -> Result<(), SimError> {
        if inputs.len() != self.actuators.len() {
            return Err(SimError::InputCount {
                expected: self.actuators.len(),
                got: inputs.len(),
            });
        }
        if !(dt.is_finite() && dt > 0.0 && dt <= 1.0) {
            return Err(SimError::Config {
                field: "dt",
                message: format!("must be within (0, 1] s, got {dt}"),
            });
        }
        let mut off = 0u32;
        for (i, inp) in inputs.iter().enumerate() {
            if matches!(inp, WheelInput::Free) {
                off |= 1 << i;
            }
        }
        if off != self.geom.off_mask {
            self.geom = Geometry::with_motors_off(&self.actual, off)?;
        }
        for (i, (a, inp)) in self.actuators.iter_mut().zip(inputs).enumerate() {
            self.dphi[i] = if self.geom.wheels[i].driven {
                a.step(*inp, dt)
            } else {
                0.0
            };
        }
        self.ground.step(
            &self.geom,
            &self.ground_params,
            &self.surface,
            &mut self.dphi,
            dt,
            &mut self.rng_ground,
        );
        for (i, (w, d)) in self.wheel_angle.iter_mut().zip(&self.dphi).enumerate() {
            *w += d;
            if off & (1 << i) != 0 {
                self.actuators[i].backdrive(*d, dt);
            }
        }
        self.t += dt;
        self.vision_new = false;
        if self.t >= self.next_vision_t - 1e-9 {
            let m = self
                .cfg
                .vision
                .measure(&self.ground.pose, &mut self.rng_vision);
            self.vision = Some((self.t, m));
            self.vision_new = true;
            self.next_vision_t += 1.0 / self.cfg.vision.rate_hz;
        }
        Ok(())
    }

    /// Restarts the travel-noise stream at the one `key` names (with the config's seed), so
    /// a caller that steps for a time it does not control (a virtual board idling in real
    /// time) can still give each trial the same realisation on every run.
    pub fn reseed_travel_noise(&mut self, key: u64) {
        let seed = self.ground_seed ^ key.wrapping_mul(0x9e37_79b9_7f4a_7c15);
        self.rng_ground = ChaCha8Rng::seed_from_u64(seed);
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.t
    }

    /// Number of wheels.
    pub fn wheel_count(&self) -> usize {
        self.actuators.len()
    }

    /// The robot the board believes it is.
    pub fn nominal(&self) -> &Robot {
        &self.nominal
    }

    /// The robot as it really is (faults applied, legs placed).
    pub fn actual(&self) -> &Robot {
        &self.actual
    }

    /// The fault numbers the run uses (effects folded in).
    pub fn faults(&self) -> &Faults {
        &self.faults
    }

    /// The floor the robot runs on.
    pub fn surface(&self) -> &Surface {
        &self.surface
    }

    /// Ground-truth pose of the body origin.
    pub fn true_pose(&self) -> Pose<f64> {
        self.ground.pose
    }

    /// Ground-truth body twist over the last tick (body frame).
    pub fn true_twist(&self) -> Twist<f64> {
        self.ground.body_twist
    }

    /// True wheel angle, rad (free wheels included).
    pub fn wheel_angle(&self, i: usize) -> f64 {
        self.wheel_angle.get(i).copied().unwrap_or(0.0)
    }

    /// The angle wheel i's encoder sees, wheel radians.
    fn encoder_angle(&self, i: usize) -> f64 {
        match (
            self.cfg.encoder_mount,
            self.nominal.wheels.get(i).map(|w| w.driven),
        ) {
            (EncoderMount::Motor, Some(true)) => self.actuators[i].motor_angle(),
            _ => self.wheel_angle(i),
        }
    }

    /// The 16-bit hardware counter of wheel i (0 for an unknown wheel).
    pub fn encoder_raw(&self, i: usize) -> u16 {
        self.encoders
            .get(i)
            .map(|e| e.raw(self.encoder_angle(i)))
            .unwrap_or(0)
    }

    /// Cumulative encoder count of wheel i since the start (what a recording's `enc_`
    /// column holds).
    pub fn encoder_count(&self, i: usize) -> i64 {
        self.encoders
            .get(i)
            .map(|e| e.count(self.encoder_angle(i)))
            .unwrap_or(0)
    }

    /// The latest vision sample (time, pose), if one was taken during the last step.
    pub fn vision(&self) -> Option<(f64, Pose<f64>)> {
        if self.vision_new {
            self.vision
        } else {
            None
        }
    }

    /// One gyro reading of the yaw rate over the last tick (draws noise on each call).
    pub fn imu_yaw_rate(&mut self) -> f64 {
        self.cfg
            .imu
            .measure(self.ground.body_twist.omega, &mut self.rng_imu)
    }

    /// Current leg angles (front, rear).
    pub fn legs(&self) -> (f64, f64) {
        self.legs
    }

    /// Cable crossings so far, per wheel.
    pub fn cable_crossings(&self) -> &[u64] {
        &self.ground.crossings
    }

    /// Microsteps wheel i's stepper has dropped.
    pub fn steps_lost(&self, i: usize) -> i64 {
        self.actuators.get(i).map(|a| a.steps_lost()).unwrap_or(0)
    }

    /// DC motor speed of wheel i in wheel rad/s (for tests of the PI loop).
    pub fn motor_rate(&self, i: usize) -> f64 {
        self.actuators
            .get(i)
            .map(|a| a.dc_wheel_rate())
            .unwrap_or(0.0)
    }

    /// PI gains suited to this robot's DC motors (see [`DcParams::pi_gains`]).
    pub fn pi_gains(&self) -> calib_core::control::PiGains {
        let gear = self.nominal.drive.gear_ratio;
        self.cfg
            .dc
            .unwrap_or_else(|| DcParams::typical(gear, 20.0))
            .with_deadband(gear, self.faults.deadband_rad_s)
            .pi_gains(gear)
    }
}
