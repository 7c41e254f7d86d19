//! Byte links between the console and a board: real serial ports (`serialport`), the
//! virtual board's pseudo-terminal, and in-memory pipes with fault injection for tests.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::io::{self, Read, Write};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::time::Duration;

/// Opens a serial port (or a pseudo-terminal) with errors a person can act on.
pub fn open_serial(port: &str, baud: u32) -> anyhow::Result<Box<dyn serialport::SerialPort>> {
    let path = std::path::Path::new(port);
    if !path.exists() {
        let found: Vec<String> = list_ports().iter().map(|p| described_port(p)).collect();
        let hint = if found.is_empty() {
            "no serial ports found".to_string()
        } else {
            format!("ports found: {}", found.join(", "))
        };
        anyhow::bail!("no such port {port} ({hint}; for a virtual board, start `wheelcal sim-board --link PATH`)");
    }
    serialport::new(port, baud).timeout(Duration::from_millis(20)).open().map_err(|e| {
        use serialport::ErrorKind;
        match e.kind() {
            ErrorKind::Io(io::ErrorKind::PermissionDenied) => anyhow::anyhow!(
                "permission denied opening {port}: add yourself to the port's group (usually `sudo usermod -aG dialout $USER`, then log in again)"
            ),
            ErrorKind::NoDevice => anyhow::anyhow!("{port} is not available: {e} (unplugged, or in use by another program?)"),
            // ENOTTY ("Inappropriate ioctl for device" / "Not a typewriter"): a file that
            // is not a terminal, such as /dev/null or a regular file.
            _ if not_a_terminal(&e) => anyhow::anyhow!(
                "{port} is not a serial port (a board shows up as /dev/ttyACM* or /dev/ttyUSB*; a virtual board as the --link of `wheelcal sim-board`)"
            ),
            _ => anyhow::anyhow!("cannot open {port}: {e}"),
        }
    })
}

/// Whether opening failed because the file is not a terminal (errno ENOTTY), whatever
/// words the C library has for it.
fn not_a_terminal(e: &serialport::Error) -> bool {
    let enotty = std::io::Error::from_raw_os_error(25).to_string();
    let d = e.description.as_str();
    d == enotty || d.contains("Not a typewriter") || d.contains("Inappropriate ioctl")
}

/// Serial ports on this machine: what `serialport` finds plus any `/dev/ttyACM*` (the
/// board's USB CDC-ACM link, which some systems list only once udev has named it).
pub fn list_ports() -> Vec<String> {
    let mut found: Vec<String> = serialport::available_ports()
        .map(|v| v.into_iter().map(|p| p.port_name).collect())
        .unwrap_or_default();
    if let Ok(dir) = std::fs::read_dir("/dev") {
        for e in dir.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with("ttyACM") {
                let path = format!("/dev/{name}");
                if !found.contains(&path) {
                    found.push(path);
                }
            }
        }
    }
    found.sort();
    found
}

/// A port's name with what it probably is, so a user picks the right one.
pub fn described_port(port: &str) -> String {
    let base = port.rsplit('/').next().unwrap_or(port);
    if base.starts_with("ttyACM") || base.starts_with("cu.usbmodem") {
        format!("{port} (USB CDC-ACM link to the board: its USB port, fast log pulls)")
    } else if base.starts_with("ttyUSB") || base.starts_with("cu.usbserial") {
        format!("{port} (USB-serial adapter: the board's UART at 115200 baud)")
    } else {
        port.to_string()
    }
}

/// A board-side stream over a serial port or pseudo-terminal master (non-blocking reads).
pub struct PortStream<P: Read + Write> {
    /// The open serial port or pseudo-terminal master.
    pub port: P,
}

impl<P: Read + Write> firmware_app::ByteStream for PortStream<P> {
    fn read(&mut self, buf: &mut [u8]) -> usize {
        // Timeout, or EIO while no client has the terminal open: nothing to read.
        self.port.read(buf).unwrap_or_default()
    }
    fn write(&mut self, data: &[u8]) {
        // A write to a terminal nobody reads may fail; the host retries what it misses.
        let _ = self.port.write_all(data);
        let _ = self.port.flush();
    }
}

/// Faults to inject on one direction of an in-memory link (probabilities per byte).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Faults {
    /// Probability per byte of losing it.
    pub drop: f64,
    /// Probability per byte of flipping one of its bits.
    pub flip: f64,
    /// Probability per byte of sending it twice.
    pub duplicate: f64,
    /// Probability per write of cutting the rest of that write off.
    pub truncate: f64,
    /// The writer stalls once, before its write number `.0` (from 0), for `.1`: a console
    /// suspended or starved of CPU while a program runs.
    pub stall: Option<(u64, Duration)>,
}

impl Faults {
    /// A clean direction: no faults.
    pub fn none() -> Self {
        Faults::default()
    }

    fn active(&self) -> bool {
        self.drop > 0.0 || self.flip > 0.0 || self.duplicate > 0.0 || self.truncate > 0.0
    }

    /// Writes a stall of `after_writes` writes then `for_` long (see [`Faults::stall`]).
    pub fn stall(after_writes: u64, for_: Duration) -> Self {
        Faults {
            stall: Some((after_writes, for_)),
            ..Faults::none()
        }
    }
}

/// The writing half of one direction: applies faults, then sends.
struct FaultyTx {
    tx: Sender<Vec<u8>>,
    faults: Faults,
    rng: ChaCha8Rng,
    writes: u64,
}

impl FaultyTx {
    fn send(&mut self, data: &[u8]) {
        if let Some((at, d)) = self.faults.stall {
            if self.writes == at {
                std::thread::sleep(d);
            }
        }
        self.writes += 1;
        if !self.faults.active() {
            let _ = self.tx.send(data.to_vec());
            return;
        }
        let mut out = Vec::with_capacity(data.len() + 4);
        for &b in data {
            if self
                .rng
                .random_bool(self.faults.truncate.min(1.0) / data.len().max(1) as f64)
            {
                break;
            }
            if self.rng.random_bool(self.faults.drop.min(1.0)) {
                continue;
            }
            let b = if self.rng.random_bool(self.faults.flip.min(1.0)) {
                b ^ (1 << self.rng.random_range(0..8))
            } else {
                b
            };
            out.push(b);
            if self.rng.random_bool(self.faults.duplicate.min(1.0)) {
                out.push(b);
            }
        }
        let _ = self.tx.send(out);
    }
}

/// One end of an in-memory duplex link.
pub struct MemoryEnd {
    tx: FaultyTx,
    rx: Receiver<Vec<u8>>,
    buf: std::collections::VecDeque<u8>,
    read_timeout: Duration,
}

/// A duplex in-memory link: `(host end, board end)`; `to_board` and `to_host` are the
/// faults on each direction, seeded for repeatability.
pub fn memory_pair(to_board: Faults, to_host: Faults, seed: u64) -> (MemoryEnd, MemoryEnd) {
    let (htx, brx) = channel();
    let (btx, hrx) = channel();
    let host = MemoryEnd {
        tx: FaultyTx {
            tx: htx,
            faults: to_board,
            rng: ChaCha8Rng::seed_from_u64(seed),
            writes: 0,
        },
        rx: hrx,
        buf: Default::default(),
        read_timeout: Duration::from_millis(5),
    };
    let board = MemoryEnd {
        tx: FaultyTx {
            tx: btx,
            faults: to_host,
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x5eed),
            writes: 0,
        },
        rx: brx,
        buf: Default::default(),
        read_timeout: Duration::ZERO,
    };
    (host, board)
}

impl Read for MemoryEnd {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        if self.buf.is_empty() {
            let chunk = if self.read_timeout.is_zero() {
                self.rx
                    .try_recv()
                    .map_err(|_| io::Error::from(io::ErrorKind::WouldBlock))
            } else {
                self.rx
                    .recv_timeout(self.read_timeout)
                    .map_err(|e| match e {
                        RecvTimeoutError::Timeout => io::Error::from(io::ErrorKind::TimedOut),
                        RecvTimeoutError::Disconnected => {
                            io::Error::from(io::ErrorKind::BrokenPipe)
                        }
                    })
            }?;
            self.buf.extend(chunk);
        }
        let n = out.len().min(self.buf.len());
        for (o, b) in out.iter_mut().zip(self.buf.drain(..n)) {
            *o = b;
        }
        Ok(n)
    }
}

impl Write for MemoryEnd {
    fn write(&mut self, data: &[u8]) -> io::Result<usize> {
        self.tx.send(data);
        Ok(data.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl firmware_app::ByteStream for MemoryEnd {
    fn read(&mut self, buf: &mut [u8]) -> usize {
        Read::read(self, buf).unwrap_or(0)
    }
    fn write(&mut self, data: &[u8]) {
        self.tx.send(data);
    }
}

#[cfg(test)]
mod port_hint_tests {
    use super::described_port;

    #[test]
    fn usb_ports_say_which_link_they_are() {
        assert!(described_port("/dev/ttyACM0").contains("USB CDC-ACM link to the board"));
        assert!(described_port("/dev/ttyUSB1").contains("UART"));
        assert_eq!(described_port("/dev/ttyS0"), "/dev/ttyS0");
    }
}
