//! Issue 14: line noise must not cut the console off the board. A `wheelcal sim-board`
//! process on a real pseudo-terminal; this test holds the port like the console does and
//! writes 10 MB of random bytes and bursts of valid-looking frames with bad CRCs into the
//! line, interleaved with valid requests that must each be answered within 1 s.

mod common;

use calib_core::protocol::{encode, Request, MAX_WIRE};
use calib_core::Corrections;
use rand::{Rng, RngCore, SeedableRng};
use std::io::Write;
use std::time::{Duration, Instant};
use wheelcal::client::Client;

/// Resident memory of a process, kB (Linux).
fn rss_kb(pid: u32) -> u64 {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    s.lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next()?.parse().ok())
        .unwrap_or(0)
}

/// A frame that looks valid (delimited, plausible length, a real body) but whose CRC is
/// wrong: the decoder must drop it and nothing may act on it.
fn bad_crc_frame(seq: u16, c: Corrections) -> Vec<u8> {
    let mut wire = [0u8; MAX_WIRE];
    let mut f = encode(seq, &Request::SetCorrections(c), &mut wire)
        .unwrap()
        .to_vec();
    // Flip a bit of an encoded byte that is neither the delimiter nor a COBS code byte
    // landing on zero: the CRC no longer matches.
    let i = f.len() / 2;
    f[i] = if f[i] ^ 0x10 == 0 {
        f[i] ^ 0x20
    } else {
        f[i] ^ 0x10
    };
    f
}

#[test]
fn noise_never_cuts_the_console_off_the_board() {
    let dir = std::env::temp_dir().join(format!("wheelcal-noise-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let board = common::Board::start("mobolab", &dir);
    let port = wheelcal::link::open_serial(board.link.to_str().unwrap(), 115_200).unwrap();
    let mut noise = port.try_clone().expect("a second handle for the noise");
    let mut client = Client::new(port, "board");
    client.hello().expect("hello");
    let factors = Corrections::DiffDrive {
        c_l: 1.01,
        c_r: 0.99,
        e_b: 1.02,
    };
    client.set_corrections(factors.clone()).unwrap();
    let rss0 = rss_kb(board.child.id());

    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(14);
    // Nobody reads while 2 MB of noise go in (a UART's other end that never listens):
    // the board answers ~8,000 damaged frames with Nacks nobody takes. A board that
    // waited for its answers to be read would stop reading too, and this write would
    // never finish: the watchdog thread fails the test instead of hanging it.
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let done2 = done.clone();
    std::thread::spawn(move || {
        std::thread::sleep(Duration::from_secs(30));
        if !done2.load(std::sync::atomic::Ordering::SeqCst) {
            eprintln!("the board stopped reading while its answers went unread");
            std::process::exit(1);
        }
    });
    let mut deaf = vec![0u8; 2_000_000];
    rng.fill_bytes(&mut deaf);
    noise.write_all(&deaf).unwrap();
    done.store(true, std::sync::atomic::Ordering::SeqCst);
    let t0 = Instant::now();
    assert_eq!(client.corrections().unwrap(), factors);
    assert!(t0.elapsed() < Duration::from_secs(1), "{:?}", t0.elapsed());
    let mut written = deaf.len();
    let mut worst = Duration::ZERO;
    let mut burst = vec![0u8; 100_000];
    let mut round = 0;
    while written < 10_000_000 {
        round += 1;
        rng.fill_bytes(&mut burst);
        noise.write_all(&burst).unwrap();
        written += burst.len();
        // Every other round, a burst of valid-looking frames with bad CRCs that would set
        // absurd factors if anything acted on them.
        if round % 2 == 0 {
            for k in 0..50 {
                let evil = Corrections::DiffDrive {
                    c_l: 0.5 + rng.random::<f64>(),
                    c_r: 1.7,
                    e_b: 0.6,
                };
                noise.write_all(&bad_crc_frame(k, evil)).unwrap();
            }
        }
        let t0 = Instant::now();
        let got = client.corrections().unwrap_or_else(|e| {
            panic!("round {round} ({written} bytes of noise): {e}");
        });
        let dt = t0.elapsed();
        worst = worst.max(dt);
        assert!(
            dt < Duration::from_secs(1),
            "round {round}: answered after {dt:?}"
        );
        assert_eq!(got, factors, "round {round}: the factors changed");
        // Now and then a valid change, which must take effect.
        if round % 25 == 0 {
            let c = Corrections::DiffDrive {
                c_l: 1.0 + round as f64 * 1e-4,
                c_r: 0.99,
                e_b: 1.02,
            };
            client.set_corrections(c.clone()).unwrap();
            assert_eq!(client.corrections().unwrap(), c);
            client.set_corrections(factors.clone()).unwrap();
        }
    }
    let rss1 = rss_kb(board.child.id());
    eprintln!(
        "10 MB of noise in {round} bursts: worst answer {worst:?}, board RSS {rss0} -> {rss1} kB"
    );
    // Bounded memory: the board keeps no backlog of what it could not send.
    assert!(
        rss1 < rss0 + 16_384,
        "board memory grew {rss0} -> {rss1} kB"
    );
}
