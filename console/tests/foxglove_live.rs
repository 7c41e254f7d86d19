//! `wheelcal status --follow --foxglove 127.0.0.1:0` against a `wheelcal sim-board`: a
//! WebSocket client (tungstenite, speaking the Foxglove SDK's protocol) subscribes to the
//! odometry and joint-state channels, and the poses and wheel rates it receives are the
//! ones the same run prints with `--json` for the same board uptime (the board's f32
//! values, within 1e-9). Loopback only.

mod common;

use ros2bag::messages::{decode, JointState, PoseStamped};
use serde_json::{json, Value};
use std::io::{BufRead, BufReader};
use std::process::Stdio;
use std::sync::mpsc;
use std::time::{Duration, Instant};
use tungstenite::client::IntoClientRequest;
use tungstenite::Message;

#[test]
fn status_follow_serves_the_boards_telemetry_to_a_foxglove_client() {
    let dir = common::scratch("foxglove-live");
    let board = common::Board::start("mobolab", &dir);
    // Somewhere off the origin, turned: the pose has all three numbers.
    let o = board.run(&["drive", "--vx", "0.2", "--omega", "0.6", "--duration", "1"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let mut child = common::wheelcal()
        .arg("--port")
        .arg(&board.link)
        .args([
            "--json",
            "status",
            "--follow",
            "--period-ms",
            "50",
            "--foxglove",
            "127.0.0.1:0",
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // stderr: the address; stdout: the telemetry lines.
    let (addr_tx, addr_rx) = mpsc::channel();
    let stderr = child.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if let Some(rest) = line.split("ws://").nth(1) {
                let a = rest.split_whitespace().next().unwrap_or("").to_string();
                let _ = addr_tx.send(a);
            }
        }
    });
    let (line_tx, line_rx) = mpsc::channel::<Value>();
    let stdout = child.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if let Ok(v) = serde_json::from_str(&line) {
                let _ = line_tx.send(v);
            }
        }
    });
    let addr = addr_rx
        .recv_timeout(Duration::from_secs(20))
        .expect("the served address on stderr");
    assert!(addr.starts_with("127.0.0.1:"), "{addr}");

    let mut req = format!("ws://{addr}").into_client_request().unwrap();
    req.headers_mut()
        .insert("sec-websocket-protocol", "foxglove.sdk.v1".parse().unwrap());
    let (mut ws, _) = tungstenite::connect(req).expect("a WebSocket connection");
    if let tungstenite::stream::MaybeTlsStream::Plain(s) = ws.get_ref() {
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    }
    // The server advertises its channels; subscribe to the odometry and joint states.
    let mut ids = std::collections::BTreeMap::new();
    let t0 = Instant::now();
    while ids.len() < 2 {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "no advertise: {ids:?}"
        );
        if let Message::Text(t) = ws.read().unwrap() {
            let v: Value = serde_json::from_str(&t).unwrap();
            if v["op"] == "advertise" {
                for c in v["channels"].as_array().unwrap() {
                    let topic = c["topic"].as_str().unwrap();
                    if topic == "/wheelcal/odometry" || topic == "/joint_states" {
                        assert_eq!(c["encoding"], "cdr");
                        assert_eq!(c["schemaEncoding"], "ros2msg");
                        ids.insert(topic.to_string(), c["id"].as_u64().unwrap());
                    }
                }
            }
        }
    }
    let subs: Vec<Value> = ids
        .values()
        .enumerate()
        .map(|(k, id)| json!({"id": k + 1, "channelId": id}))
        .collect();
    ws.send(Message::Text(
        json!({"op": "subscribe", "subscriptions": subs})
            .to_string()
            .into(),
    ))
    .unwrap();
    let sub_of = |topic: &str| ids.keys().position(|k| k == topic).unwrap() as u32 + 1;
    let (sub_pose, sub_joints) = (sub_of("/wheelcal/odometry"), sub_of("/joint_states"));

    // Pose and joint messages by stamp (ns), until three poses match printed samples.
    let mut poses = std::collections::BTreeMap::new();
    let mut joints = std::collections::BTreeMap::new();
    let mut printed = std::collections::BTreeMap::new();
    let mut matched = 0;
    let mut worst = 0f64;
    let t0 = Instant::now();
    while matched < 3 {
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "{} poses, {} printed, {matched} matched",
            poses.len(),
            printed.len()
        );
        if let Message::Binary(b) = ws.read().unwrap() {
            assert_eq!(b[0], 1, "message data");
            let sub = u32::from_le_bytes(b[1..5].try_into().unwrap());
            let ns = u64::from_le_bytes(b[5..13].try_into().unwrap());
            if sub == sub_pose {
                let m: PoseStamped = decode(&b[13..]).unwrap();
                assert_eq!(m.header.stamp.ns() as u64, ns);
                poses.insert(ns, m);
            } else if sub == sub_joints {
                let m: JointState = decode(&b[13..]).unwrap();
                joints.insert(ns, m);
            }
        }
        while let Ok(v) = line_rx.try_recv() {
            let ns = v["uptime_ms"].as_u64().unwrap() * 1_000_000;
            printed.insert(ns, v);
        }
        matched = 0;
        for (ns, m) in &poses {
            let (Some(s), Some(j)) = (printed.get(ns), joints.get(ns)) else {
                continue;
            };
            // The board's f32 numbers, as printed (shortest f32 form) and as served.
            let f32_of = |v: &Value| v.as_f64().unwrap() as f32 as f64;
            let (x, y, th) = (
                f32_of(&s["pose"]["x"]),
                f32_of(&s["pose"]["y"]),
                f32_of(&s["pose"]["theta"]),
            );
            let q = m.pose.orientation;
            let yaw = 2.0 * q.z.atan2(q.w);
            let dyaw = (yaw - th + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            worst = worst
                .max((m.pose.position.x - x).abs())
                .max((m.pose.position.y - y).abs())
                .max(dyaw.abs());
            assert!(x.abs() > 0.05 && th.abs() > 0.3, "the board moved: {s}");
            assert_eq!(j.name, ["left", "right"]);
            for (got, want) in j.velocity.iter().zip(s["wheel_rates"].as_array().unwrap()) {
                worst = worst.max((got - f32_of(want)).abs());
            }
            matched += 1;
        }
    }
    println!("{matched} samples matched, worst |served - printed| {worst:.1e}");
    assert!(worst <= 1e-9, "{worst}");
    let _ = ws.close(None);
    common::signal(&child, "-INT");
    let st = common::wait_exit(
        &mut child,
        Duration::from_secs(10),
        "status --follow ends on SIGINT",
    );
    assert!(st.success(), "{st:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
