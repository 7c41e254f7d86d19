//! Two links (the firmware's USART2 and USB CDC-ACM) on one application: each link has
//! its own `Server` (framing state, retry cache, telemetry sequence), both act on the
//! same `App`. Requests interleaved byte by byte must each be answered on their own link,
//! what one link sets the other reads, and damage on one link disturbs only that link.

mod common;

use calib_core::protocol::{decode_frame, encode, Request, Response, MAX_WIRE};
use calib_core::Corrections;
use common::*;
use firmware_app::{defaults, SaveQueue, Server, Step, TelemetryRoute};

fn frame(seq: u16, req: &Request) -> Vec<u8> {
    let mut out = [0u8; MAX_WIRE];
    encode(seq, req, &mut out).expect("fits").to_vec()
}

/// Feeds one byte to a link's server; returns the answer it produced, if any (saves
/// succeed at once, as the host's virtual board does them).
fn push(server: &mut Server, b: &mut Bench, byte: u8) -> Option<Vec<u8>> {
    let now = b.now();
    match server.push(byte, &mut b.app, now) {
        Step::Idle => None,
        Step::Send(w) => Some(w.to_vec()),
        Step::Persist { seq, .. } => {
            let r = b.app.persisted(true);
            Some(server.reply(seq, &r).to_vec())
        }
    }
}

/// Sends `a` on link A and `b_bytes` on link B, alternating byte by byte (the worst
/// interleaving for shared framing state); returns each link's answers.
fn interleaved(
    b: &mut Bench,
    sa: &mut Server,
    a: &[u8],
    sb: &mut Server,
    b_bytes: &[u8],
) -> (Vec<Vec<u8>>, Vec<Vec<u8>>) {
    let (mut out_a, mut out_b) = (Vec::new(), Vec::new());
    for i in 0..a.len().max(b_bytes.len()) {
        if let Some(&x) = a.get(i) {
            out_a.extend(push(sa, b, x));
        }
        if let Some(&x) = b_bytes.get(i) {
            out_b.extend(push(sb, b, x));
        }
    }
    (out_a, out_b)
}

fn decoded(wire: &[u8]) -> (u16, Response<'static>) {
    let mut w = wire.to_vec();
    let f = decode_frame(&mut w).expect("intact answer");
    let r: Response<'_> = f.decode().expect("a response");
    // Only owned variants are compared here (no log chunks).
    let r = match r {
        Response::LogChunk(_) => panic!("no log chunks in this test"),
        Response::Ok => Response::Ok,
        Response::Corrections(c) => Response::Corrections(c),
        Response::Params(p) => Response::Params(p),
        Response::Status(s) => Response::Status(s),
        Response::Info(i) => Response::Info(i),
        Response::Rejected(r) => Response::Rejected(r),
        Response::Nack(e) => Response::Nack(e),
        other => panic!("unexpected answer {other:?}"),
    };
    (f.seq, r)
}

fn bench() -> Bench {
    let params = defaults::params();
    let robot = params.robot.clone();
    Bench::new(params, Corrections::None, &robot)
}

#[test]
fn two_links_share_one_app_and_keep_their_own_framing() {
    let mut b = bench();
    let (mut sa, mut sb) = (Server::new(), Server::new());
    let good = Corrections::DiffDrive {
        c_l: 1.01,
        c_r: 0.99,
        e_b: 1.02,
    };

    // A sets corrections while B asks for the parameters, the same sequence number on both.
    let (a, bb) = interleaved(
        &mut b,
        &mut sa,
        &frame(1, &Request::SetCorrections(good.clone())),
        &mut sb,
        &frame(1, &Request::GetParams),
    );
    assert_eq!(
        (a.len(), bb.len()),
        (1, 1),
        "one answer per request and link"
    );
    assert_eq!(decoded(&a[0]), (1, Response::Ok));
    assert_eq!(decoded(&bb[0]), (1, Response::Params(defaults::params())));

    // Both read the corrections A set: one application behind both links.
    let (a, bb) = interleaved(
        &mut b,
        &mut sa,
        &frame(2, &Request::GetCorrections),
        &mut sb,
        &frame(2, &Request::GetCorrections),
    );
    assert_eq!(decoded(&a[0]), (2, Response::Corrections(good.clone())));
    assert_eq!(decoded(&bb[0]), (2, Response::Corrections(good.clone())));

    // The retry cache is per link: B repeating A's last request (same sequence number and
    // body) is a new request on B, executed and answered there, while a true retry on A is
    // answered from A's cache with the same bytes.
    let stop = frame(3, &Request::Stop);
    let (a1, b1) = interleaved(&mut b, &mut sa, &stop, &mut sb, &stop);
    assert_eq!(decoded(&a1[0]), (3, Response::Ok));
    assert_eq!(decoded(&b1[0]), (3, Response::Ok));
    let (a2, b2) = interleaved(&mut b, &mut sa, &stop, &mut sb, &[]);
    assert_eq!(a2, a1, "retry on A answered from A's cache");
    assert!(b2.is_empty());

    // Damage on A (a corrupted frame and line noise) is nacked on A only; B's request,
    // interleaved with it, is answered intact and nothing changes.
    let mut damaged = frame(4, &Request::ResetCorrections);
    damaged[3] ^= 0x40;
    damaged.extend_from_slice(&[0x55, 0xAA, 0x13, 0x00, 0x07, 0x7E, 0x00]);
    let before = format!("{:?}", b.app.snapshot());
    let (a, bb) = interleaved(
        &mut b,
        &mut sa,
        &damaged,
        &mut sb,
        &frame(4, &Request::GetCorrections),
    );
    assert_eq!(before, format!("{:?}", b.app.snapshot()));
    assert!(!a.is_empty());
    for x in &a {
        assert!(
            matches!(decoded(x).1, Response::Nack(_)),
            "A's answers are nacks"
        );
    }
    assert_eq!(bb.len(), 1);
    assert_eq!(decoded(&bb[0]), (4, Response::Corrections(good)));
    assert_eq!(b.app.status().bad_frames as usize, a.len());
}

/// What the board's link task does with a link's answer: an answered frame routes
/// telemetry to that link ([`TelemetryRoute::spoke`]).
fn request_on(
    route: &TelemetryRoute,
    id: u8,
    server: &mut Server,
    b: &mut Bench,
    req: &Request,
    seq: u16,
) {
    let mut answered = false;
    for byte in frame(seq, req) {
        answered |= push(server, b, byte).is_some();
    }
    assert!(answered, "link {id} got no answer");
    route.spoke(id);
}

/// Telemetry frames each link would send over `ms` milliseconds: the board's link task
/// asks its server for one every tick when the route points at it.
fn telemetry_over(
    route: &TelemetryRoute,
    b: &mut Bench,
    links: &mut [(u8, &mut Server)],
    ms: u64,
) -> Vec<usize> {
    let mut counts = vec![0; links.len()];
    for _ in 0..ms {
        b.tick();
        for (k, (id, server)) in links.iter_mut().enumerate() {
            if route.gets_telemetry(*id) && server.telemetry(&mut b.app).is_some() {
                counts[k] += 1;
            }
        }
    }
    counts
}

/// Issue 20.5: the rule that telemetry goes only to the link that last received a valid
/// frame lived in the embassy glue, untested. At a 100 ms period over 1 s: none before
/// either link speaks, ten frames to A once A has spoken and none to B, then all to B
/// once B speaks.
#[test]
fn telemetry_goes_only_to_the_link_that_spoke_last() {
    let mut b = bench();
    let route = TelemetryRoute::new();
    let (mut sa, mut sb) = (Server::new(), Server::new());
    let period = Request::SetTelemetry { period_ms: 100 };
    // The period is set on the application directly: no link has spoken.
    let now = b.now();
    let _ = b.app.handle(period.clone(), now);
    let counts = telemetry_over(&route, &mut b, &mut [(1, &mut sa), (2, &mut sb)], 1000);
    assert_eq!(counts, [0, 0], "telemetry before any link spoke");
    request_on(&route, 1, &mut sa, &mut b, &period, 1);
    let counts = telemetry_over(&route, &mut b, &mut [(1, &mut sa), (2, &mut sb)], 1000);
    assert!(
        (10..=11).contains(&counts[0]) && counts[1] == 0,
        "{counts:?}"
    );
    request_on(&route, 2, &mut sb, &mut b, &Request::GetStatus, 1);
    let counts = telemetry_over(&route, &mut b, &mut [(1, &mut sa), (2, &mut sb)], 1000);
    assert!(
        counts[0] == 0 && (10..=11).contains(&counts[1]),
        "{counts:?}"
    );
}

/// Issue 20.5: two links saving at once (both asked SaveCorrections in the same
/// millisecond) each get their own write's result, in turn: the storage task writes A's
/// item, A gets that result (a failed write here), and only then is B's item handed over
/// (and succeeds). Without the turn, both items queue and the one result signal can
/// wake the wrong link.
#[test]
fn saves_from_two_links_take_turns_and_get_their_own_results() {
    use embassy_futures::block_on;
    use embassy_futures::join::join3;
    use embassy_futures::yield_now;
    use embassy_sync::blocking_mutex::raw::NoopRawMutex;
    use firmware_app::PersistItem;
    use std::cell::RefCell;

    let queue: SaveQueue<NoopRawMutex> = SaveQueue::new();
    let log = RefCell::new(Vec::<String>::new());
    let item = |c: f64| {
        PersistItem::Corrections(Corrections::DiffDrive {
            c_l: c,
            c_r: 1.0,
            e_b: 1.0,
        })
    };
    let name = |i: &PersistItem| match i {
        PersistItem::Corrections(Corrections::DiffDrive { c_l, .. }) if *c_l == 1.01 => "A",
        PersistItem::Corrections(_) => "B",
        PersistItem::Params(_) => "params",
    };
    let link_a = async {
        let ok = queue.save(item(1.01)).await;
        log.borrow_mut().push(format!("A got {ok}"));
    };
    // B asks a moment after A, and is polled before A from then on (the worst order for
    // the single result signal: B would be the one to take A's result).
    let link_b = async {
        yield_now().await;
        let ok = queue.save(item(1.02)).await;
        log.borrow_mut().push(format!("B got {ok}"));
    };
    let storage = async {
        // The first write fails (a worn sector), the second works; each takes a while.
        for ok in [false, true] {
            let i = queue.next().await;
            log.borrow_mut().push(format!("wrote {}", name(&i)));
            for _ in 0..3 {
                yield_now().await;
            }
            queue.finished(ok);
        }
    };
    block_on(join3(link_b, link_a, storage));
    assert_eq!(
        log.into_inner(),
        ["wrote A", "A got false", "wrote B", "B got true"]
    );
}
