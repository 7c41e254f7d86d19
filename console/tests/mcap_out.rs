//! `wheelcal log pull --out FILE.mcap` and the replayed-path MCAP, read back with the
//! mcap crate: channels, schemas, message counts and timestamps.

use calib_core::motion::OmniPath;
use calib_core::protocol::ProgramSpec;
use formats::robot_file;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;
use wheelcal::link::Faults;
use wheelcal::mcap_out::{write_paths, PathSeries, TRIAL_TOPICS};
use wheelcal::virtual_board::InProcessBoard;

/// Messages per topic: (log time ns, JSON body).
type Topics = BTreeMap<String, Vec<(u64, serde_json::Value)>>;

fn read(path: &Path) -> (Vec<u8>, Topics) {
    let bytes = std::fs::read(path).unwrap();
    let mut by_topic = Topics::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m
            .channel
            .schema
            .as_ref()
            .expect("every channel has a schema");
        assert_eq!(schema.encoding, "jsonschema");
        assert_eq!(m.channel.message_encoding, "json");
        let _: serde_json::Value = serde_json::from_slice(&schema.data).expect("schema is JSON");
        by_topic
            .entry(m.channel.topic.clone())
            .or_default()
            .push((m.log_time, serde_json::from_slice(&m.data).unwrap()));
    }
    (bytes, by_topic)
}

#[test]
fn a_pulled_trial_as_mcap_has_one_channel_per_signal_group() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let robot = robot_file::load(&root.join("robots/omni4.toml")).unwrap();
    let sim = sim::SimRobot::new(
        &robot,
        sim::Faults::none(4),
        sim::Surface::flat(),
        sim::SimConfig::default(),
    )
    .unwrap();
    let mut board = InProcessBoard::start(&robot, sim, Faults::none(), Faults::none(), 3).unwrap();
    let c = &mut board.client;
    c.timeout = Duration::from_secs(2);
    c.hello().unwrap();
    let rate = 50u16;
    c.run_program(
        ProgramSpec::Omni {
            idle: calib_core::protocol::IdleWheels::Released,
            path: OmniPath::W1,
            length_m: 0.5,
        },
        rate,
        calib_core::protocol::DEFAULT_LINK_TIMEOUT_MS,
    )
    .unwrap();
    wheelcal::board::wait_program(c, Duration::from_secs(120), |_| {}).unwrap();
    let dir = std::env::temp_dir().join(format!("wheelcal-mcap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("trial.mcap");
    let info = c.trials().unwrap().trials.last().unwrap().clone();
    let pulled = wheelcal::board::pull_trial(c, info.id, &out, |_, _| {}).unwrap();
    let (_, topics) = read(&out);
    let names: Vec<&str> = topics.keys().map(|s| s.as_str()).collect();
    let mut want = TRIAL_TOPICS.to_vec();
    want.sort();
    assert_eq!(names, want);
    let k = pulled.records;
    assert_eq!(k as u32, info.records);
    for t in &TRIAL_TOPICS[..3] {
        assert_eq!(topics[*t].len(), k, "{t}");
    }
    assert_eq!(topics[TRIAL_TOPICS[3]].len(), 2, "status at start and end");
    // Timestamps: board uptime at the trial's start plus one record period (1/rate) per
    // record, within the board's 1 ms tick; the first record comes at the first logged
    // tick, within one period of the start.
    let odo = &topics[TRIAL_TOPICS[2]];
    let start = info.start_ms * 1_000_000;
    let period = 1e9 / rate as f64;
    assert!(odo[0].0 >= start && ((odo[0].0 - start) as f64) < period);
    for w in odo.windows(2) {
        let dt = (w[1].0 - w[0].0) as f64;
        assert!((dt - period).abs() <= 1e6, "{dt}");
    }
    // The omni path W1 is 0.5 m along +x: the last odometry pose says so (within 5 %).
    let last = &odo[k - 1].1;
    assert!((last["x"].as_f64().unwrap() - 0.5).abs() < 0.025, "{last}");
    let enc = &topics[TRIAL_TOPICS[1]][k - 1].1;
    assert_eq!(enc["counts"].as_array().unwrap().len(), 4);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn replayed_paths_as_mcap() {
    let dir = std::env::temp_dir().join(format!("wheelcal-paths-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("paths.mcap");
    let t: Vec<f64> = (0..100).map(|i| i as f64 * 0.01).collect();
    let nominal: Vec<_> = t.iter().map(|&t| (t, 0.0)).collect();
    let fitted: Vec<_> = t.iter().map(|&t| (t, 0.1 * t)).collect();
    write_paths(
        &[
            PathSeries {
                name: "nominal",
                t: &t,
                xy: &nominal,
            },
            PathSeries {
                name: "fitted",
                t: &t[..50],
                xy: &fitted,
            },
        ],
        &out,
    )
    .unwrap();
    let (_, topics) = read(&out);
    assert_eq!(topics["/paths/nominal"].len(), 100);
    assert_eq!(topics["/paths/fitted"].len(), 50);
    let (t, m) = &topics["/paths/fitted"][49];
    assert_eq!(*t, 490_000_000);
    assert!((m["y"].as_f64().unwrap() - 0.049).abs() < 1e-12);
    let _ = std::fs::remove_dir_all(&dir);
}
