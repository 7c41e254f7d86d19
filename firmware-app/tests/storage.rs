//! Persistence on sequential-storage's mock flash: power cuts at every step of a save, and
//! boot-time validation.

use calib_core::protocol::{Params, Stored};
use calib_core::robot::presets;
use calib_core::Corrections;
use embassy_futures::block_on;
use firmware_app::{defaults, PersistItem, Store};
use sequential_storage::mock_flash::{MockFlashBase, WriteCountCheck};

/// 4 pages of 1 KiB with 4-byte words, like a small slice of the STM32's flash.
type Flash = MockFlashBase<4, 4, 256>;

fn store(flash: Flash) -> Store<Flash> {
    Store::new(flash, Flash::FULL_FLASH_RANGE).unwrap()
}

fn diff(c_l: f64) -> Corrections {
    Corrections::DiffDrive {
        c_l,
        c_r: 0.99,
        e_b: 1.02,
    }
}

fn fresh() -> Flash {
    Flash::new(WriteCountCheck::Twice, None, true)
}

#[test]
fn fresh_flash_boots_with_defaults_and_says_so() {
    let mut s = store(fresh());
    let l = block_on(s.load());
    assert_eq!(l.params, defaults::params());
    assert_eq!(l.corrections, Corrections::None);
    assert_eq!(
        (l.boot.params, l.boot.corrections),
        (Stored::Missing, Stored::Missing)
    );
}

#[test]
fn saved_values_survive_a_reboot() {
    let mut s = store(fresh());
    block_on(s.save(&PersistItem::Corrections(diff(1.01)))).unwrap();
    let mut p = defaults::params();
    p.gains.kp = 0.07;
    block_on(s.save(&PersistItem::Params(p.clone()))).unwrap();
    let mut s = store(s.into_flash());
    let l = block_on(s.load());
    assert_eq!((l.params, l.corrections), (p, diff(1.01)));
    assert_eq!(
        (l.boot.params, l.boot.corrections),
        (Stored::Loaded, Stored::Loaded)
    );
}

/// The power fails after k flash operations of a save, for every k until the save
/// completes; each time the board reboots on what the flash holds. It must find the old
/// or the new factors, never anything else. Saves are repeated so the map also has to
/// erase and migrate pages while being cut.
#[test]
fn a_power_cut_at_every_step_of_a_save_leaves_old_or_new() {
    let mut flash = fresh();
    let mut old = diff(1.0);
    block_on(store(flash.clone()).save(&PersistItem::Corrections(old.clone()))).unwrap();
    {
        let mut s = store(flash);
        block_on(s.save(&PersistItem::Corrections(old.clone()))).unwrap();
        flash = s.into_flash();
    }
    let mut cuts = 0;
    let mut saw_old = 0;
    let mut saw_new = 0;
    for round in 0..12 {
        let new = diff(1.0 + 0.01 * (round + 1) as f64);
        let mut k = 0u32;
        loop {
            let mut f = flash.clone();
            f.bytes_until_shutoff = Some(k);
            let mut s = store(f);
            let res = block_on(s.save(&PersistItem::Corrections(new.clone())));
            let mut f = s.into_flash();
            f.bytes_until_shutoff = None;
            // Reboot on whatever the flash holds now.
            let mut s = store(f);
            let l = block_on(s.load());
            assert_eq!(l.boot.corrections, Stored::Loaded, "round {round}, cut {k}");
            if res.is_ok() {
                assert_eq!(l.corrections, new);
                flash = s.into_flash();
                break;
            }
            cuts += 1;
            if l.corrections == old {
                saw_old += 1;
            } else if l.corrections == new {
                saw_new += 1;
            } else {
                panic!("round {round}, cut {k}: garbage {:?}", l.corrections);
            }
            k += 1;
        }
        old = new;
    }
    println!("{cuts} power cuts: {saw_old} kept the old factors, {saw_new} had the new");
    assert!(cuts > 100 && saw_old > 0);
}

/// Values that were stored but are no longer acceptable are reported and replaced.
#[test]
fn invalid_stored_values_become_defaults_and_are_reported() {
    let mut s = store(fresh());
    // The store writes what it is given; the request handler validates before saving, so
    // an out-of-range value can only come from an older firmware or a bug: it must not be
    // used.
    block_on(s.save(&PersistItem::Corrections(diff(5.0)))).unwrap();
    let l = block_on(s.load());
    assert_eq!(l.corrections, Corrections::None);
    assert_eq!(l.boot.corrections, Stored::Invalid);

    // Factors that do not fit the stored robot (differential factors on an omni robot).
    block_on(s.save(&PersistItem::Corrections(diff(1.01)))).unwrap();
    let omni = Params {
        robot: presets::omni4(),
        ..defaults::params()
    };
    block_on(s.save(&PersistItem::Params(omni.clone()))).unwrap();
    let l = block_on(s.load());
    assert_eq!(l.params, omni);
    assert_eq!(
        (l.boot.params, l.boot.corrections),
        (Stored::Loaded, Stored::Invalid)
    );

    // Parameters out of range.
    let mut bad = defaults::params();
    bad.gains.kp = f32::NAN;
    block_on(s.save(&PersistItem::Params(bad))).unwrap();
    let l = block_on(s.load());
    assert_eq!(l.params, defaults::params());
    assert_eq!(l.boot.params, Stored::Invalid);
}

/// Bits flipped in flash are caught (sequential-storage's item CRC or ours) and reported,
/// never used.
#[test]
fn corrupted_flash_is_reported() {
    let mut s = store(fresh());
    block_on(s.save(&PersistItem::Corrections(diff(1.01)))).unwrap();
    let f = s.into_flash();
    // Flip a bit in every written byte of the first page's item area, one at a time.
    let written: Vec<usize> = f
        .as_bytes()
        .iter()
        .enumerate()
        .take(1024)
        .filter(|(_, b)| **b != 0xFF)
        .map(|(i, _)| i)
        .collect();
    // harmless, invalid (corrupted), storage error, missing
    let mut outcomes = [0usize; 4];
    for &i in &written {
        let mut g = f.clone();
        g.as_bytes_mut()[i] ^= 0x10;
        let mut s = store(g);
        let l = block_on(s.load());
        match (l.boot.corrections, &l.corrections) {
            (Stored::Loaded, c) => {
                assert_eq!(*c, diff(1.01), "byte {i}: a changed value was used");
                outcomes[0] += 1;
            }
            (state, c) => {
                assert_eq!(*c, Corrections::None);
                outcomes[match state {
                    Stored::Invalid => 1,
                    Stored::StorageError => 2,
                    _ => 3,
                }] += 1;
            }
        }
    }
    println!(
        "{} bytes flipped: {} harmless, {} corrupted, {} storage error, {} missing",
        written.len(),
        outcomes[0],
        outcomes[1],
        outcomes[2],
        outcomes[3]
    );
    assert!(outcomes[1] > 0);
    // A saved calibration that became unreadable is never reported as "never saved".
    assert_eq!(outcomes[3], 0, "a corrupted item read as missing");
}

/// The byte-stream path the virtual board uses: SetCorrections then SaveCorrections through
/// `Server::poll`, the save done by the async store under `block_on`; after a "reboot" the
/// board boots with the saved factors.
#[test]
fn save_through_the_server_survives_a_reboot() {
    use calib_core::protocol::{decode_frame, encode, Request, Response, MAX_WIRE};
    use calib_core::protocol::{BootReport, Stored};
    use firmware_app::{App, ByteStream, Server};
    use std::collections::VecDeque;

    #[derive(Default)]
    struct Pipe {
        to_board: VecDeque<u8>,
        from_board: Vec<u8>,
    }
    impl ByteStream for Pipe {
        fn read(&mut self, buf: &mut [u8]) -> usize {
            let n = buf.len().min(self.to_board.len());
            for b in buf.iter_mut().take(n) {
                *b = self.to_board.pop_front().unwrap();
            }
            n
        }
        fn write(&mut self, data: &[u8]) {
            self.from_board.extend_from_slice(data);
        }
    }

    let mut s = store(fresh());
    let loaded = block_on(s.load());
    let mut log = vec![0u8; 1024];
    let mut app = App::new(loaded.params, loaded.corrections, loaded.boot, &mut log, 0);
    let mut server = Server::new();
    let mut pipe = Pipe::default();
    let mut out = [0u8; MAX_WIRE];
    for (seq, req) in [
        (1, Request::SetCorrections(diff(1.03))),
        (2, Request::SaveCorrections),
    ] {
        pipe.to_board
            .extend(encode(seq, &req, &mut out).unwrap().iter().copied());
    }
    server.poll(&mut app, &mut pipe, 0, |item| {
        block_on(s.save(item)).is_ok()
    });
    let mut answers = pipe
        .from_board
        .split_mut(|&b| b == 0)
        .filter(|f| !f.is_empty());
    for want_seq in [1, 2] {
        let f = decode_frame(answers.next().expect("an answer")).unwrap();
        assert_eq!(f.seq, want_seq);
        assert_eq!(f.decode::<Response>().unwrap(), Response::Ok);
    }
    let mut s = store(s.into_flash());
    let l = block_on(s.load());
    assert_eq!(l.corrections, diff(1.03));
    assert_eq!(
        l.boot,
        BootReport {
            corrections: Stored::Loaded,
            params: Stored::Missing
        }
    );
}

/// Issue 23 §5: random bytes over a flash (a damaged image, a wrong file), or every
/// written byte inverted at once, read "none saved": the saves' record was unreadable and
/// the store took an unreadable record for no saves. A flash that holds data but no
/// readable record is now corrupted (or a storage error), never "none saved"; a flash
/// never written stays "none saved".
#[test]
fn damaged_flash_is_never_none_saved() {
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let check = |f: Flash, what: &str| {
        let l = block_on(store(f).load());
        assert_eq!(l.corrections, Corrections::None, "{what}");
        for state in [l.boot.corrections, l.boot.params] {
            assert!(
                matches!(state, Stored::Invalid | Stored::StorageError),
                "{what}: {state:?}"
            );
        }
    };
    for trial in 0..50 {
        let mut f = fresh();
        for b in f.as_bytes_mut().iter_mut() {
            *b = next() as u8;
        }
        check(f, &format!("random bytes #{trial}"));
    }
    // A saved calibration with every written byte inverted.
    let mut s = store(fresh());
    block_on(s.save(&PersistItem::Corrections(diff(1.01)))).unwrap();
    let mut f = s.into_flash();
    for b in f.as_bytes_mut().iter_mut().filter(|b| **b != 0xFF) {
        *b = !*b;
    }
    let l = block_on(store(f).load());
    assert_ne!(l.boot.corrections, Stored::Missing);
    assert_ne!(l.boot.corrections, Stored::Loaded);
    // Never written: none saved.
    let l = block_on(store(fresh()).load());
    assert_eq!(l.boot.corrections, Stored::Missing);
}

/// A turn law (protocol v5's `DiffDriveTurnLaw`) saved over plain factors survives a
/// reboot to the bit, and plain factors saved before it still read back as they were
/// written (the new kind is last on the wire, so older values keep their encoding).
#[test]
fn a_saved_turn_law_survives_a_reboot() {
    let mut s = store(fresh());
    block_on(s.save(&PersistItem::Corrections(diff(1.01)))).unwrap();
    let mut s = store(s.into_flash());
    assert_eq!(block_on(s.load()).corrections, diff(1.01));
    let law = Corrections::DiffDriveTurnLaw {
        c_l: 1.01,
        c_r: 0.99,
        e_b: 1.02,
        e_b_arc: 0.0057,
    };
    block_on(s.save(&PersistItem::Corrections(law.clone()))).unwrap();
    let mut s = store(s.into_flash());
    let l = block_on(s.load());
    assert_eq!(l.corrections, law);
    assert_eq!(l.boot.corrections, Stored::Loaded);
}

/// A differential drive's three laws (protocol v6's `DiffDriveLaws`) saved over a turn
/// law survive a reboot to the bit; the turn law saved before them read back as written.
#[test]
fn saved_laws_survive_a_reboot() {
    let mut s = store(fresh());
    let turn = Corrections::DiffDriveTurnLaw {
        c_l: 1.01,
        c_r: 0.99,
        e_b: 1.02,
        e_b_arc: 0.0057,
    };
    block_on(s.save(&PersistItem::Corrections(turn.clone()))).unwrap();
    let mut s = store(s.into_flash());
    assert_eq!(block_on(s.load()).corrections, turn);
    let laws = Corrections::DiffDriveLaws {
        c_l: 1.01,
        c_r: 0.99,
        e_b: 1.02,
        laws: calib_core::correction::DiffLaws {
            e_b_arc: 0.0057,
            speed_rel: -0.035,
            accel_slip_s: 0.047,
        },
    };
    block_on(s.save(&PersistItem::Corrections(laws.clone()))).unwrap();
    let mut s = store(s.into_flash());
    let l = block_on(s.load());
    assert_eq!(l.corrections, laws);
    assert_eq!(l.boot.corrections, Stored::Loaded);
}

/// Laws with the range they were fitted on (protocol v9's `DiffDriveLawsInRange`) saved
/// over v6's `DiffDriveLaws` survive a reboot to the bit (the range too); the laws saved
/// before them read back as written.
#[test]
fn saved_laws_with_their_range_survive_a_reboot() {
    let mut s = store(fresh());
    let laws = calib_core::correction::DiffLaws {
        e_b_arc: 0.0057,
        speed_rel: -0.035,
        accel_slip_s: 0.0,
    };
    let old = Corrections::DiffDriveLaws {
        c_l: 1.01,
        c_r: 0.99,
        e_b: 1.02,
        laws,
    };
    block_on(s.save(&PersistItem::Corrections(old.clone()))).unwrap();
    let mut s = store(s.into_flash());
    assert_eq!(block_on(s.load()).corrections, old);
    let within = Corrections::DiffDriveLawsInRange {
        c_l: 1.01,
        c_r: 0.99,
        e_b: 1.02,
        laws,
        range: [0.02, 1.0, 0.41],
    };
    block_on(s.save(&PersistItem::Corrections(within.clone()))).unwrap();
    let mut s = store(s.into_flash());
    let l = block_on(s.load());
    assert_eq!(l.corrections, within);
    assert_eq!(l.boot.corrections, Stored::Loaded);
    assert_eq!(l.corrections.law_range().speed_max_m_s, 0.41);
}

/// An omni robot's turn law (protocol v8's `OmniTurnLaw`) saved over plain omni factors
/// survives a reboot to the bit; the plain factors saved before it read back as written
/// (the new kind is last on the wire).
#[test]
fn a_saved_omni_turn_law_survives_a_reboot() {
    let mut s = store(fresh());
    let params = Params {
        robot: presets::omni3(0.04, 0.15),
        ..defaults::params()
    };
    block_on(s.save(&PersistItem::Params(params.clone()))).unwrap();
    let plain = Corrections::Omni {
        f_lat: heapless::Vec::from_slice(&[1.01, 0.99, 1.0]).unwrap(),
        f_lon: 1.02,
    };
    block_on(s.save(&PersistItem::Corrections(plain.clone()))).unwrap();
    let mut s = store(s.into_flash());
    assert_eq!(block_on(s.load()).corrections, plain);
    let law = Corrections::OmniTurnLaw {
        f_lat: heapless::Vec::from_slice(&[1.01, 0.99, 1.0]).unwrap(),
        f_lon: 1.02,
        l_arc: 0.0187,
    };
    block_on(s.save(&PersistItem::Corrections(law.clone()))).unwrap();
    let mut s = store(s.into_flash());
    let l = block_on(s.load());
    assert_eq!((l.params, l.corrections), (params, law));
    assert_eq!(l.boot.corrections, Stored::Loaded);
}
