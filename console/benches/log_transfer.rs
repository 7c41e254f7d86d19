//! Log transfer from a virtual board: bytes per record of the compressed log (delta +
//! zigzag varint blocks) against the fixed records it replaced, on typical drives
//! (UMBmark square, omni path, standing still), the wire bytes and the time a 60 s /
//! 1 kHz / 4-wheel trial takes at 115,200 baud (arithmetic from the wire bytes measured),
//! and the host's pull / decode / CSV throughput over an in-memory link.
//!
//! `cargo bench -p wheelcal --bench log_transfer`

use calib_core::motion::{Direction, OmniPath, Segment};
use calib_core::protocol::{record_size, ProgramSpec};
use formats::robot_file;
use std::path::Path;
use std::time::{Duration, Instant};
use wheelcal::board::records_to_csv;
use wheelcal::client::decode_records;
use wheelcal::link::Faults;
use wheelcal::virtual_board::InProcessBoard;

const BAUD_BYTES_PER_S: f64 = 115_200.0 / 10.0;

fn trial(robot_name: &str, what: &str, program: ProgramSpec) -> f64 {
    let robot = robot_file::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../robots")
            .join(robot_name),
    )
    .unwrap();
    let n = robot.wheel_count();
    let sim = sim::SimRobot::new(
        &robot,
        sim::Faults::none(n),
        sim::Surface::flat(),
        sim::SimConfig::default(),
    )
    .unwrap();
    let mut board = InProcessBoard::start(&robot, sim, Faults::none(), Faults::none(), 1).unwrap();
    let c = &mut board.client;
    c.timeout = Duration::from_secs(2);
    c.hello().unwrap();
    c.run_program(program, 1000, calib_core::protocol::DEFAULT_LINK_TIMEOUT_MS)
        .unwrap();
    wheelcal::board::wait_program(c, Duration::from_secs(600), |_| {}).unwrap();
    let info = c.trials().unwrap().trials.last().unwrap().clone();
    let (rx0, tx0) = (c.stats.bytes_received, c.stats.bytes_sent);
    let t0 = Instant::now();
    let data = c.pull_log(info.id, Vec::new(), |_, _| {}).unwrap();
    let pull = t0.elapsed();
    let (rx, tx) = (c.stats.bytes_received - rx0, c.stats.bytes_sent - tx0);
    let t1 = Instant::now();
    let recs = decode_records(&info, &data).unwrap();
    let decode = t1.elapsed();
    let t2 = Instant::now();
    let mut csv = Vec::with_capacity(16 << 20);
    records_to_csv(&robot, &info, &recs, &mut csv).unwrap();
    let export = t2.elapsed();
    let k = recs.len() as f64;
    let fixed = record_size(n) as f64;
    let per = data.len() as f64 / k;
    println!("{what} ({robot_name}, {n} wheels, 1 kHz)");
    println!(
        "  records            {} in {} bytes: {per:.2} bytes/record (fixed {fixed}): {:.2}x fewer",
        recs.len(),
        data.len(),
        fixed / per
    );
    println!(
        "  wire board->host   {rx} bytes ({:.2} per record), host->board {tx} bytes ({:.1} % payload both ways)",
        rx as f64 / k,
        100.0 * data.len() as f64 / (rx + tx) as f64
    );
    println!(
        "  this trial at 115200 baud: {:.1} s (fixed records: {:.1} s)",
        rx as f64 / BAUD_BYTES_PER_S,
        rx as f64 / BAUD_BYTES_PER_S * fixed / per
    );
    println!(
        "  pull in memory {:.3} s, decode {:.1} M records/s, CSV {:.1} ms ({} bytes)",
        pull.as_secs_f64(),
        k / decode.as_secs_f64() / 1e6,
        export.as_secs_f64() * 1e3,
        csv.len()
    );
    rx as f64 / k
}

fn main() {
    let mut four = Vec::new();
    trial(
        "mobolab.toml",
        "UMBmark square 2 m",
        ProgramSpec::Umbmark {
            side_m: 2.0,
            dir: Direction::Ccw,
        },
    );
    four.push(trial(
        "omni4.toml",
        "UMBmark square 2 m",
        ProgramSpec::Umbmark {
            side_m: 2.0,
            dir: Direction::Cw,
        },
    ));
    four.push(trial(
        "omni4.toml",
        "omni path W1 2 m",
        ProgramSpec::Omni {
            path: OmniPath::W1,
            length_m: 2.0,
            idle: calib_core::protocol::IdleWheels::Released,
        },
    ));
    let still = heapless::Vec::from_slice(&[Segment::Pause { duration_s: 60.0 }]).unwrap();
    four.push(trial(
        "omni4.toml",
        "standing still 60 s",
        ProgramSpec::Custom(still),
    ));
    let worst = four.iter().cloned().fold(0.0, f64::max);
    println!(
        "60 s / 1 kHz / 4 wheels at 115200 baud: {:.1} s at the worst 4-wheel drive above ({worst:.2} wire bytes/record); fixed 48-byte records: {:.1} s",
        60_000.0 * worst / BAUD_BYTES_PER_S,
        60_000.0 * (48.0 * 1.03) / BAUD_BYTES_PER_S
    );
}
