//! `wheelcal status --follow --foxglove [ADDR]`: the board's telemetry served live to
//! Foxglove through the Foxglove SDK's WebSocket server (the `foxglove` crate; protocol
//! subprotocol `foxglove.sdk.v1`). Open it in Foxglove with *Open connection* ->
//! *Foxglove WebSocket* -> `ws://ADDR`.
//!
//! The channels carry the same ROS 2 messages as the MCAP files ([`crate::mcap_out`]:
//! CDR, `ros2msg` schemas), stamped with the board's uptime:
//! - `/wheelcal/odometry`: `geometry_msgs/msg/PoseStamped`, the board's odometry in
//!   frame `odom`;
//! - `/tf`: `tf2_msgs/msg/TFMessage`, the same pose as `odom` -> `base_link`;
//! - `/joint_states`: `sensor_msgs/msg/JointState`, the measured wheel rates (rad/s) as
//!   velocities (telemetry has no counts, so no positions);
//! - `/wheelcal/wheel_commands`: `sensor_msgs/msg/JointState`, the commanded rates.
//!
//! The server is the console's cargo feature `foxglove` (off by default: the Foxglove SDK
//! and its tokio stack are 60-odd crates a clone's first build would otherwise wait for).
//! Without it `--foxglove` is refused with [`NOT_BUILT`] before the board is opened.

use anyhow::{anyhow, Result};
use calib_core::protocol::Status;
use calib_core::robot::Robot;
use std::net::{IpAddr, SocketAddr};
#[cfg(feature = "foxglove")]
use {
    crate::mcap_out::{ros2, BASE_FRAME, ODOM_FRAME},
    anyhow::Context as _,
    foxglove::{ChannelBuilder, Context, PartialMetadata, RawChannel, Schema, WebSocketServer},
    serde::Serialize,
    std::sync::Arc,
};

/// What `--foxglove` says in a wheelcal built without the feature `foxglove`.
pub const NOT_BUILT: &str = "--foxglove: this wheelcal was built without the live Foxglove server (the cargo feature `foxglove`, off by default); build it with `cargo build --release -p wheelcal --features foxglove` or install it with `cargo install --path console --features foxglove`. Without it, `log pull` to a .mcap file and `--report` still write MCAP files Foxglove opens";

/// Whether this wheelcal serves `--foxglove` (built with the feature `foxglove`).
pub const BUILT: bool = cfg!(feature = "foxglove");

/// Refuses `--foxglove` with [`NOT_BUILT`] in a wheelcal built without the server.
pub fn require_built() -> Result<()> {
    if BUILT {
        Ok(())
    } else {
        Err(anyhow!(NOT_BUILT))
    }
}

/// The address `--foxglove` serves on without one: loopback, Foxglove's usual port.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";

/// Topics served, in [`Live::publish`]'s order.
pub const LIVE_TOPICS: [&str; 4] = [
    "/wheelcal/odometry",
    "/tf",
    "/joint_states",
    "/wheelcal/wheel_commands",
];

/// A running server and its channels.
#[cfg(feature = "foxglove")]
pub struct Live {
    server: Option<foxglove::WebSocketServerHandle>,
    addr: SocketAddr,
    channels: [Arc<RawChannel>; 4],
    names: Vec<String>,
    /// The context the channels and the server live in (they hold it weakly).
    _ctx: Arc<Context>,
}

/// `ADDR` as `HOST:PORT`, `HOST` (port 8765) or `PORT` (on 127.0.0.1); port 0 takes a
/// free one.
pub fn parse_addr(s: &str) -> Result<SocketAddr> {
    if let Ok(a) = s.parse::<SocketAddr>() {
        return Ok(a);
    }
    if let Ok(ip) = s.parse::<IpAddr>() {
        return Ok(SocketAddr::new(ip, 8765));
    }
    if let Ok(port) = s.parse::<u16>() {
        return Ok(SocketAddr::from(([127, 0, 0, 1], port)));
    }
    Err(anyhow!(
        "--foxglove {s}: give an address as 127.0.0.1:8765, an IP (port 8765) or a port (on 127.0.0.1)"
    ))
}

/// No server in a wheelcal built without the feature `foxglove`: none can be made
/// ([`Live::start`] refuses with [`NOT_BUILT`]).
#[cfg(not(feature = "foxglove"))]
pub enum Live {}

#[cfg(not(feature = "foxglove"))]
impl Live {
    /// Refused: this wheelcal has no server ([`NOT_BUILT`]).
    pub fn start(_addr: SocketAddr, _robot: &Robot) -> Result<Live> {
        Err(anyhow!(NOT_BUILT))
    }

    /// The address served.
    pub fn addr(&self) -> SocketAddr {
        match *self {}
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        match *self {}
    }

    /// Sends one telemetry sample to the connected clients.
    pub fn publish(&self, _s: &Status) -> Result<()> {
        match *self {}
    }
}

#[cfg(feature = "foxglove")]
impl Live {
    /// Starts the server on `addr` with the channels of `robot`'s wheels.
    pub fn start(addr: SocketAddr, robot: &Robot) -> Result<Live> {
        let ctx = Context::new();
        let channel = |i: usize, ty: &str| -> Result<Arc<RawChannel>> {
            let text = ros2::schema(ty).with_context(|| format!("no schema for {ty}"))?;
            ChannelBuilder::new(LIVE_TOPICS[i])
                .message_encoding("cdr")
                .schema(Schema::new(ty, "ros2msg", text.into_bytes()))
                .context(&ctx)
                .build_raw()
                .map_err(|e| anyhow!("cannot make the channel {}: {e}", LIVE_TOPICS[i]))
        };
        let channels = [
            channel(0, ros2::POSE_STAMPED)?,
            channel(1, ros2::TF_MESSAGE)?,
            channel(2, ros2::JOINT_STATE)?,
            channel(3, ros2::JOINT_STATE)?,
        ];
        let server = WebSocketServer::new()
            .name("wheelcal")
            .bind(addr.ip().to_string(), addr.port())
            .context(&ctx)
            .start_blocking()
            .map_err(|e| anyhow!("--foxglove {addr}: cannot serve: {e}"))?;
        let addr = SocketAddr::new(addr.ip(), server.port());
        Ok(Live {
            server: Some(server),
            addr,
            channels,
            names: robot.wheels.iter().map(|w| w.name.to_string()).collect(),
            _ctx: ctx,
        })
    }

    /// The address served (with the port taken when 0 was asked for).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.server.as_ref().map_or(0, |s| s.client_count())
    }

    fn put<T: Serialize>(&self, i: usize, ns: u64, msg: &T) -> Result<()> {
        let data = ros2::cdr(msg).map_err(|e| anyhow!("CDR: {e}"))?;
        self.channels[i].log_with_meta(&data, PartialMetadata { log_time: Some(ns) });
        Ok(())
    }

    /// Sends one telemetry sample to the connected clients.
    pub fn publish(&self, s: &Status) -> Result<()> {
        let ns = s.uptime_ms.saturating_mul(1_000_000);
        let header = |frame: &str| ros2::Header {
            stamp: ros2::Time::from_ns(ns),
            frame_id: frame.into(),
        };
        let pose = ros2::Pose::planar(s.pose.x as f64, s.pose.y as f64, s.pose.theta as f64);
        self.put(
            0,
            ns,
            &ros2::PoseStamped {
                header: header(ODOM_FRAME),
                pose,
            },
        )?;
        self.put(
            1,
            ns,
            &ros2::TfMessage::one(header(ODOM_FRAME), BASE_FRAME, &pose),
        )?;
        let joints = |v: &[f32]| ros2::JointState {
            header: header(BASE_FRAME),
            name: self.names.iter().take(v.len()).cloned().collect(),
            position: Vec::new(),
            velocity: v.iter().take(self.names.len()).map(|&r| r as f64).collect(),
            effort: Vec::new(),
        };
        self.put(2, ns, &joints(&s.wheel_rates))?;
        self.put(3, ns, &joints(&s.wheel_cmds))?;
        Ok(())
    }
}

#[cfg(feature = "foxglove")]
impl Drop for Live {
    fn drop(&mut self) {
        if let Some(s) = self.server.take() {
            s.stop().wait_blocking();
        }
    }
}
