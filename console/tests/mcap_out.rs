//! `wheelcal log pull --out FILE.mcap` and the replayed-path MCAP, read back with the
//! mcap crate and decoded with the bag importer's CDR types (`ros2bag::messages`):
//! channels, schemas, message counts and timestamps. tests/interop.rs decodes the same
//! files with Python's readers.

use calib_core::motion::OmniPath;
use calib_core::protocol::ProgramSpec;
use formats::robot_file;
use ros2bag::messages::{decode, JointState, PoseStamped, TFMessage};
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;
use wheelcal::link::Faults;
use wheelcal::mcap_out::{write_pose_paths, PoseSeries, TRIAL_TOPICS};
use wheelcal::virtual_board::InProcessBoard;

/// Messages per topic: (log time ns, schema name, CDR bytes).
type Topics = BTreeMap<String, Vec<(u64, String, Vec<u8>)>>;

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
        assert_eq!(schema.encoding, "ros2msg");
        assert_eq!(m.channel.message_encoding, "cdr");
        by_topic.entry(m.channel.topic.clone()).or_default().push((
            m.log_time,
            schema.name.clone(),
            m.data.to_vec(),
        ));
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
    for t in &TRIAL_TOPICS {
        assert_eq!(topics[*t].len(), k, "{t}");
    }
    // Timestamps: board uptime at the trial's start plus one record period (1/rate) per
    // record, within the board's 1 ms tick; the first record comes at the first logged
    // tick, within one period of the start.
    let odo = &topics[TRIAL_TOPICS[0]];
    let start = info.start_ms * 1_000_000;
    let period = 1e9 / rate as f64;
    assert!(odo[0].0 >= start && ((odo[0].0 - start) as f64) < period);
    for w in odo.windows(2) {
        let dt = (w[1].0 - w[0].0) as f64;
        assert!((dt - period).abs() <= 1e6, "{dt}");
    }
    // The omni path W1 is 0.5 m along +x: the last odometry pose says so (within 5 %).
    assert_eq!(odo[0].1, "geometry_msgs/msg/PoseStamped");
    let last: PoseStamped = decode(&odo[k - 1].2).unwrap();
    assert!((last.pose.position.x - 0.5).abs() < 0.025, "{last:?}");
    let tf: TFMessage = decode(&topics[TRIAL_TOPICS[1]][k - 1].2).unwrap();
    assert_eq!(
        tf.transforms[0].transform.translation.x,
        last.pose.position.x
    );
    let js: JointState = decode(&topics[TRIAL_TOPICS[2]][k - 1].2).unwrap();
    assert_eq!(js.name, ["w1", "w2", "w3", "w4"]);
    assert_eq!(js.position.len(), 4);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn replayed_paths_as_mcap() {
    let dir = std::env::temp_dir().join(format!("wheelcal-paths-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("paths.mcap");
    let t: Vec<f64> = (0..100).map(|i| i as f64 * 0.01).collect();
    let nominal: Vec<_> = t.iter().map(|&t| (t, 0.0, 0.0)).collect();
    let fitted: Vec<_> = t.iter().map(|&t| (t, 0.1 * t, 2.0 * t)).collect();
    write_pose_paths(
        &[
            PoseSeries {
                name: "nominal",
                t: &t,
                pose: &nominal,
            },
            PoseSeries {
                name: "fitted",
                t: &t[..50],
                pose: &fitted,
            },
        ],
        &out,
    )
    .unwrap();
    let (_, topics) = read(&out);
    assert_eq!(topics["/paths/nominal"].len(), 100);
    assert_eq!(topics["/paths/fitted"].len(), 50);
    assert_eq!(topics["/tf"].len(), 150);
    let (t, _, data) = &topics["/paths/fitted"][49];
    assert_eq!(*t, 490_000_000);
    let m: PoseStamped = decode(data).unwrap();
    assert_eq!(m.header.frame_id, "world");
    assert_eq!(m.header.stamp.nanosec, 490_000_000);
    assert!((m.pose.position.y - 0.049).abs() < 1e-12);
    let q = m.pose.orientation;
    assert!((2.0 * q.z.atan2(q.w) - 0.98).abs() < 1e-12);
    let _ = std::fs::remove_dir_all(&dir);
}
