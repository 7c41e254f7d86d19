//! Corrupted bags never panic, abort or lose data silently (issue 52, items 1 and 7).
//!
//! The bags are written by an independent writer (Python's `rosbags`, `tests/make_bag.py`),
//! compressed (zstd chunks, as `ros2 bag record` writes them) and not, then mutated byte by
//! byte with a fixed-seed generator so that every run tries the same cases:
//!
//! - 2,400 single- and multi-byte mutations at random offsets through the bag reader
//!   ([`Bag::open`]), where the panics were (`capacity overflow` in the `mcap` crate's
//!   chunk decompression, and allocations of 8.9e18 bytes that abort), and 300 of them
//!   through the whole import (CDR decoding and the conversion of what was decoded);
//! - each chunk's stated uncompressed size set to absurd values;
//! - every byte of the summary section (the chunk index) changed: the data section is
//!   whole, so the import must equal the original's, row for row.
//!
//! Each case must return, either an error or a result; a result read from a damaged bag
//! must say so (`Bag::damage`, or the import's notes) unless it lost nothing.
//! Needs python3 with rosbags (`bash scripts/setup.sh`); without it the tests fail.

use ros2bag::bag::Bag;
use ros2bag::{import, ImportOptions};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::process::Command;

const WANTED: [&str; 3] = ["/joint_states", "/mocap/pose", "/cmd_vel"];

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ros2bag-fuzz-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn robot_file() -> PathBuf {
    testdata::real("diff-square-run-01").join("robot.toml")
}

/// A synthetic drive of `seconds` as one `.mcap` file (bytes and path).
fn bag(name: &str, seconds: u32, compress: bool) -> (PathBuf, Vec<u8>) {
    let out = tmp(name).join("bag");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/make_bag.py");
    let robot = robot_file();
    let mut cmd = Command::new("python3");
    cmd.arg(&script)
        .args(["--robot", robot.to_str().unwrap()])
        .args(["--synthetic", &seconds.to_string()])
        .args(["--out", out.to_str().unwrap()]);
    if compress {
        cmd.arg("--compress");
    }
    let o = cmd
        .output()
        .expect("python3 with rosbags is needed: bash scripts/setup.sh");
    assert!(
        o.status.success(),
        "make_bag.py: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let file = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|e| e == "mcap"))
        .expect("an .mcap file");
    let bytes = std::fs::read(&file).unwrap();
    (file, bytes)
}

fn opts() -> ImportOptions {
    ImportOptions {
        pose_topic: "/mocap/pose".into(),
        pose_frame: Some("map".into()),
        ..ImportOptions::default()
    }
}

/// A fixed-seed xorshift: the same cases on every run.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// Messages of the wanted topics a bag read gives.
fn messages(b: &Bag) -> usize {
    b.messages.values().map(Vec::len).sum()
}

/// Reads `bytes` as a bag at `file`; `Err` holds a panic's message.
fn read(file: &Path, bytes: &[u8]) -> Result<Result<Bag, String>, String> {
    std::fs::write(file, bytes).unwrap();
    catch_unwind(AssertUnwindSafe(|| {
        Bag::open(file, &WANTED).map_err(|e| e.to_string())
    }))
    .map_err(|p| {
        p.downcast_ref::<String>()
            .cloned()
            .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default()
    })
}

/// Mutates 1-4 bytes of `good` at random offsets (or one byte to 0x00/0xff/random).
fn mutate(good: &[u8], rng: &mut Rng) -> (Vec<u8>, Vec<usize>) {
    let mut b = good.to_vec();
    let n = 1 + rng.below(4);
    let mut at = Vec::new();
    for _ in 0..n {
        let i = rng.below(b.len());
        b[i] = match rng.below(3) {
            0 => 0x00,
            1 => 0xff,
            _ => rng.next() as u8,
        };
        at.push(i);
    }
    (b, at)
}

/// Every mutation returns; a read that reports no damage kept every message or lost one
/// only where a byte of that message's own record changed (its channel id or topic).
fn fuzz_reader(name: &str, compress: bool, cases: usize, seed: u64) {
    let (file, good) = bag(name, 120, compress);
    let base = Bag::open(&file, &WANTED).unwrap();
    assert!(base.damage.is_none());
    let total = messages(&base);
    assert!(total > 15_000, "{total} messages");
    let mut rng = Rng(seed);
    let mut panics = Vec::new();
    let (mut errors, mut damaged, mut whole) = (0, 0, 0);
    for _ in 0..cases {
        let (b, at) = mutate(&good, &mut rng);
        match read(&file, &b) {
            Err(p) => panics.push(format!("bytes {at:?}: {p}")),
            Ok(Err(_)) => errors += 1,
            Ok(Ok(bag)) if bag.damage.is_some() => damaged += 1,
            Ok(Ok(bag)) => {
                // Unreported loss: more than the (at most 4) messages whose records the
                // mutation touched.
                let got = messages(&bag);
                assert!(
                    got + at.len() >= total,
                    "bytes {at:?} lost {} of {total} messages without a word",
                    total - got
                );
                whole += 1;
            }
        }
    }
    println!(
        "{name}: {cases} mutations: {errors} errors, {damaged} damaged and said so, {whole} read whole, {} panics",
        panics.len()
    );
    assert!(
        panics.is_empty(),
        "{} panics:\n{}",
        panics.len(),
        panics.join("\n")
    );
}

#[test]
fn mutated_compressed_bags_never_panic() {
    fuzz_reader("zstd", true, 1200, 0x5eed_0001);
}

#[test]
fn mutated_uncompressed_bags_never_panic() {
    fuzz_reader("plain", false, 1200, 0x5eed_0002);
}

/// The record layout (MCAP spec): opcode u8, length u64, body. Returns (offset, opcode,
/// body offset, body length) for each top-level record up to the footer.
fn records(b: &[u8]) -> Vec<(usize, u8, usize, usize)> {
    let mut v = Vec::new();
    let mut i = 8;
    while i + 9 <= b.len() {
        let op = b[i];
        let len = u64::from_le_bytes(b[i + 1..i + 9].try_into().unwrap()) as usize;
        v.push((i, op, i + 9, len));
        if op == 0x02 {
            break;
        }
        i += 9 + len;
    }
    v
}

/// A chunk's uncompressed size (bytes 16..24 of its body) set to absurd values, as the
/// probe's `memory allocation of 8863084066665136347 bytes failed`: an error naming the
/// chunk, no abort.
#[test]
fn absurd_chunk_sizes_are_errors_not_allocations() {
    let (file, good) = bag("sizes", 120, true);
    let chunks: Vec<_> = records(&good).into_iter().filter(|r| r.1 == 0x06).collect();
    assert!(chunks.len() >= 4, "{} chunks", chunks.len());
    for (k, &(at, _, body, _)) in chunks.iter().enumerate() {
        for size in [
            8_863_084_066_665_136_347u64,
            u64::MAX,
            1 << 40,
            3 << 30,
            0,
            1,
        ] {
            let mut b = good.clone();
            b[body + 16..body + 24].copy_from_slice(&size.to_le_bytes());
            let got = read(&file, &b).unwrap_or_else(|p| panic!("chunk {k}, size {size}: {p}"));
            match got {
                Err(e) => panic!("chunk {k}, size {size}: the whole bag refused: {e}"),
                Ok(bag) => {
                    let d = bag
                        .damage
                        .unwrap_or_else(|| panic!("chunk {k}, size {size}: no damage reported"));
                    assert_eq!(d.offset, Some(at as u64), "chunk {k}: {d}");
                }
            }
        }
    }
    // The import refuses it naming the chunk's offset, unless asked to keep what came before.
    let robot = formats::robot_file::load(&robot_file()).unwrap();
    let mut b = good.clone();
    let (at, _, body, _) = chunks[2];
    b[body + 16..body + 24].copy_from_slice(&8_863_084_066_665_136_347u64.to_le_bytes());
    std::fs::write(&file, &b).unwrap();
    let e = import(&file, &robot, &opts()).unwrap_err().to_string();
    assert!(
        e.contains(&at.to_string()) && e.contains("--keep-partial"),
        "{e}"
    );
}

/// The summary (chunk index, statistics) is only an index: a damaged byte there must not
/// drop a chunk (the probe lost 38 s of 600 with exit 0). Every 19th byte of the summary
/// section is changed in turn; the import equals the original's.
#[test]
fn a_damaged_chunk_index_loses_nothing() {
    let (file, good) = bag("index", 120, true);
    let robot = formats::robot_file::load(&robot_file()).unwrap();
    let want = import(&file, &robot, &opts()).unwrap().recording;
    let footer = good.len() - 8 - 29;
    assert_eq!(good[footer], 0x02, "footer record");
    let summary_start =
        u64::from_le_bytes(good[footer + 9..footer + 17].try_into().unwrap()) as usize;
    assert!(summary_start > 0 && summary_start < footer);
    let mut tried = 0;
    for i in (summary_start..footer).step_by(19) {
        let mut b = good.clone();
        b[i] ^= 0x5a;
        std::fs::write(&file, &b).unwrap();
        let got = catch_unwind(AssertUnwindSafe(|| import(&file, &robot, &opts())))
            .unwrap_or_else(|_| panic!("byte {i}: panic"))
            .unwrap_or_else(|e| panic!("byte {i}: {e}"));
        assert_eq!(got.recording.len(), want.len(), "byte {i}: rows");
        assert_eq!(got.recording.t, want.t, "byte {i}: times");
        assert_eq!(got.recording.x, want.x, "byte {i}: poses");
        tried += 1;
    }
    assert!(tried > 20, "{tried} summary bytes tried");
}

/// 300 mutations through the whole import, compressed and not: an error or a recording,
/// never a panic, and never a non-finite value in what is written.
#[test]
fn mutated_bags_import_or_fail_cleanly() {
    let robot = formats::robot_file::load(&robot_file()).unwrap();
    let mut panics = Vec::new();
    for (name, compress, seed) in [("imp-zstd", true, 7u64), ("imp-plain", false, 11)] {
        let (file, good) = bag(name, 30, compress);
        let mut rng = Rng(seed);
        for _ in 0..150 {
            let (b, at) = mutate(&good, &mut rng);
            std::fs::write(&file, &b).unwrap();
            let mut o = opts();
            o.keep_partial = true;
            match catch_unwind(AssertUnwindSafe(|| import(&file, &robot, &o))) {
                Err(_) => panics.push(format!("{name} bytes {at:?}")),
                Ok(Err(_)) => {}
                Ok(Ok(imp)) => {
                    let r = &imp.recording;
                    for v in
                        r.t.iter()
                            .chain(r.x.iter().flatten())
                            .chain(r.theta.iter().flatten())
                    {
                        assert!(
                            v.is_finite(),
                            "{name} bytes {at:?}: a non-finite value imported"
                        );
                    }
                }
            }
        }
    }
    assert!(panics.is_empty(), "panics: {panics:?}");
}

/// A bag folder of `seconds` with `extra` make_bag.py arguments.
fn bag_with(name: &str, seconds: u32, extra: &[&str]) -> PathBuf {
    let out = tmp(name).join("bag");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/make_bag.py");
    let robot = robot_file();
    let o = Command::new("python3")
        .arg(&script)
        .args(["--robot", robot.to_str().unwrap()])
        .args(["--synthetic", &seconds.to_string()])
        .args(["--out", out.to_str().unwrap()])
        .args(extra)
        .output()
        .expect("python3 with rosbags is needed: bash scripts/setup.sh");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

/// Messages that decode but cannot be data (issue 52 §7: a NaN joint became count 0, inf
/// became 9223372036854775807, a zero quaternion theta = NaN, a stamp at 2^31 - 1 s a
/// 538,800,308 s recording): an error naming the topic, the kind and the time; with
/// --keep-partial the sample is dropped, said, and the rest equals the clean import.
#[test]
fn decodable_but_impossible_values_are_refused_by_name() {
    let robot = formats::robot_file::load(&robot_file()).unwrap();
    let clean = import(&bag_with("clean", 20, &[]), &robot, &opts()).unwrap();
    let n = clean.recording.len();
    // Joints are sampled every 10 ms, poses at 7 ms past every 30 ms.
    for (kind, at, topic, says) in [
        ("nan-joint", "10.000", "/joint_states", "NaN"),
        ("inf-joint", "10.000", "/joint_states", "inf"),
        ("zero-quat", "9.997", "/mocap/pose", "quaternion"),
        ("far-stamp", "10.000", "/joint_states", "hour"),
    ] {
        let b = bag_with(kind, 20, &["--poison", &format!("{kind}@{at}")]);
        let e = import(&b, &robot, &opts()).unwrap_err().to_string();
        assert!(
            e.contains(topic) && e.contains(says) && e.contains("--keep-partial"),
            "{kind}: {e}"
        );
        if kind != "far-stamp" {
            assert!(
                e.contains(&format!("at {at} s")),
                "{kind}: the time is named: {e}"
            );
        }
        let mut o = opts();
        o.keep_partial = true;
        let imp = import(&b, &robot, &o).unwrap();
        assert!(
            imp.notes
                .iter()
                .any(|s| s.contains("refused") && s.contains(topic)),
            "{kind}: {:?}",
            imp.notes
        );
        let r = &imp.recording;
        // One joint sample fewer, or the same rows with one pose sample fewer.
        assert!(
            r.len() == n || r.len() == n - 1,
            "{kind}: {} rows of {n}",
            r.len()
        );
        assert!(
            r.t.last().unwrap() < &21.0,
            "{kind}: {} s long",
            r.t.last().unwrap()
        );
        for w in &r.wheels {
            let enc = w.enc.as_ref().unwrap();
            assert!(
                enc.iter().flatten().all(|c| c.abs() < 1_000_000),
                "{kind}: counts"
            );
        }
        assert!(
            r.theta.iter().flatten().all(|v| v.is_finite()),
            "{kind}: theta"
        );
    }
}

/// metadata.yaml over 1 MiB, or listing one file twice, is refused naming the file.
#[test]
fn damaged_metadata_is_refused_by_name() {
    let robot = formats::robot_file::load(&robot_file()).unwrap();
    let b = bag_with("meta", 5, &[]);
    let meta = b.join("metadata.yaml");
    let text = std::fs::read_to_string(&meta).unwrap();
    let twice = text.replace("  - bag.mcap", "  - bag.mcap\n  - bag.mcap");
    assert_ne!(twice, text, "{text}");
    std::fs::write(&meta, &twice).unwrap();
    let e = import(&b, &robot, &opts()).unwrap_err().to_string();
    assert!(
        e.contains("metadata.yaml") && e.contains("more than once"),
        "{e}"
    );
    let mut big = text.clone();
    big.push_str(&format!("# {}\n", "x".repeat(2 << 20)));
    std::fs::write(&meta, &big).unwrap();
    let e = import(&b, &robot, &opts()).unwrap_err().to_string();
    assert!(e.contains("metadata.yaml") && e.contains("MiB"), "{e}");
}
