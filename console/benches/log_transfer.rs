//! Log transfer from a virtual board: protocol efficiency (payload / wire bytes), time to
//! pull 100 000 records over an in-memory link (no baud-rate limit: this measures the
//! protocol and both ends' code, not a UART), and decode throughput.
//!
//! `cargo bench -p wheelcal --bench log_transfer`

use calib_core::motion::Segment;
use calib_core::protocol::ProgramSpec;
use formats::robot_file;
use std::path::Path;
use std::time::{Duration, Instant};
use wheelcal::board_cmds::records_to_csv;
use wheelcal::client::decode_records;
use wheelcal::link::Faults;
use wheelcal::virtual_board::InProcessBoard;

fn main() {
    let robot =
        robot_file::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/omni4.toml"))
            .unwrap();
    let sim = sim::SimRobot::new(
        &robot,
        sim::Faults::none(4),
        sim::Surface::flat(),
        sim::SimConfig::default(),
    )
    .unwrap();
    let mut board = InProcessBoard::start(&robot, sim, Faults::none(), Faults::none(), 1).unwrap();
    let c = &mut board.client;
    c.timeout = Duration::from_secs(2);
    c.hello().unwrap();
    // 100 s standing still, logged at 1 kHz: 100 000 records of 4 wheels (48 bytes each).
    let program = heapless::Vec::from_slice(&[Segment::Pause { duration_s: 100.0 }]).unwrap();
    c.run_program(ProgramSpec::Custom(program), 1000).unwrap();
    wheelcal::board_cmds::wait_program(c, Duration::from_secs(600), |_| {}).unwrap();
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

    println!(
        "records            {} ({} bytes each, {} bytes)",
        recs.len(),
        info.record_size,
        data.len()
    );
    println!(
        "wire, board->host  {rx} bytes: payload efficiency {:.1} %",
        100.0 * data.len() as f64 / rx as f64
    );
    println!(
        "wire, both ways    {} bytes: payload efficiency {:.1} %",
        rx + tx,
        100.0 * data.len() as f64 / (rx + tx) as f64
    );
    println!(
        "at 115200 baud     {:.1} s (10 bits per byte on the UART)",
        rx as f64 * 10.0 / 115_200.0
    );
    println!(
        "pull (in memory)   {:.3} s, {:.1} MB/s",
        pull.as_secs_f64(),
        data.len() as f64 / pull.as_secs_f64() / 1e6
    );
    println!(
        "decode             {:.2} ms, {:.1} M records/s",
        decode.as_secs_f64() * 1e3,
        recs.len() as f64 / decode.as_secs_f64() / 1e6
    );
    println!(
        "export CSV         {:.1} ms ({} bytes)",
        export.as_secs_f64() * 1e3,
        csv.len()
    );
}
