//! An MCAP file's data section, walked record by record with every length the file states
//! bounded before anything is allocated.
//!
//! Why not the `mcap` crate's readers: they size their buffers from the chunk headers
//! (`uncompressed_size`), so one changed byte in a compressed chunk made them panic
//! (`capacity overflow`) or abort (an allocation of 8.9e18 bytes), and the indexed reader
//! trusts the summary, so a changed byte in the chunk index dropped a whole chunk. Here
//! the summary is not read at all (the data section holds every schema, channel and
//! message in order), each record's length must fit in what is left of the file, and a
//! chunk decompresses as a stream into a buffer that grows only as output really arrives,
//! stopped one byte past the size the chunk states (and never past [`MAX_CHUNK_BYTES`]).
//! The `mcap` crate still parses each record's body, on a slice of exactly its length.
//!
//! A chunk is all or nothing: its records are handed on only when the whole chunk
//! decompresses to its stated size, matches its CRC and parses.

use mcap::records::Record;
use std::collections::BTreeMap;
use std::io::Read;

/// The file's first 8 bytes (MCAP spec).
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// The largest chunk accepted, uncompressed. rosbag2 writes chunks of about 1 MiB and the
/// MCAP tools of at most a few; a chunk stating more than this is taken as damaged, not
/// as a reason to hold a quarter of a gigabyte per chunk.
pub const MAX_CHUNK_BYTES: u64 = 256 << 20;

const OP_FOOTER: u8 = 0x02;
const OP_SCHEMA: u8 = 0x03;
const OP_CHANNEL: u8 = 0x04;
const OP_MESSAGE: u8 = 0x05;
const OP_CHUNK: u8 = 0x06;
const OP_MESSAGE_INDEX: u8 = 0x07;
const OP_DATA_END: u8 = 0x0F;

/// One record the reader cares about.
#[derive(Debug, Clone, PartialEq)]
pub enum Item<'a> {
    /// A schema: its id and name (the ROS type, e.g. `sensor_msgs/msg/JointState`).
    Schema {
        /// Schema id (0 is never a schema).
        id: u16,
        /// Its name.
        name: String,
    },
    /// A channel: a topic and its schema.
    Channel {
        /// Channel id.
        id: u16,
        /// The schema's id (0: none).
        schema_id: u16,
        /// The topic.
        topic: String,
        /// Message encoding (`cdr`).
        encoding: String,
    },
    /// A message.
    Message {
        /// The channel it was logged on.
        channel_id: u16,
        /// When the recorder received it, ns since the epoch.
        log_time_ns: u64,
        /// Its serialised bytes.
        data: &'a [u8],
    },
}

/// Where and why the walk stopped early.
#[derive(Debug, Clone, PartialEq)]
pub struct Stop {
    /// Byte offset of the top-level record that could not be read.
    pub offset: u64,
    /// What is wrong with it.
    pub message: String,
    /// Log times (ns) of the messages the file states after that point, where the
    /// records' framing still held: the span of what was lost.
    pub lost_ns: Option<(u64, u64)>,
}

/// Walks `buf` (a whole `.mcap` file), handing each schema, channel and message of the
/// data section to `visit` in file order. `Err(text)`: not an MCAP file at all. `Ok(None)`:
/// read to the end of the data section; `Ok(Some(stop))`: stopped at damage, everything
/// before it was handed on.
pub fn walk(buf: &[u8], visit: &mut dyn FnMut(Item<'_>)) -> Result<Option<Stop>, String> {
    if buf.len() < MAGIC.len() || &buf[..MAGIC.len()] != MAGIC {
        return Err("not an MCAP file (it does not start with the MCAP magic bytes)".into());
    }
    let mut at = MAGIC.len();
    while at < buf.len() {
        let (op, body) = match frame(buf, at) {
            Ok(f) => f,
            Err(message) => {
                return Ok(Some(Stop {
                    offset: at as u64,
                    message,
                    lost_ns: None,
                }))
            }
        };
        let next = at + 9 + body.len();
        match op {
            OP_FOOTER | OP_DATA_END => return Ok(None),
            OP_CHUNK => {
                let checked = chunk_items(body).and_then(|c| {
                    let items = parse_all(&c.records)?;
                    agrees_with_its_span(&items, c.span)?;
                    if !c.crc_checked {
                        agrees_with_its_index(&items, buf, next)?;
                    }
                    items.into_iter().for_each(&mut *visit);
                    Ok(())
                });
                if let Err(message) = checked {
                    return Ok(Some(stop_at(buf, at, message, body)));
                }
            }
            OP_SCHEMA | OP_CHANNEL | OP_MESSAGE => match item(op, body) {
                Ok(Some(i)) => visit(i),
                Ok(None) => {}
                Err(message) => {
                    return Ok(Some(Stop {
                        offset: at as u64,
                        message,
                        lost_ns: lost_after(buf, next),
                    }))
                }
            },
            _ => {}
        }
        at = next;
    }
    Ok(None)
}

/// The record at `at`: its opcode and body, the body's stated length checked against
/// what is left of the file.
fn frame(buf: &[u8], at: usize) -> Result<(u8, &[u8]), String> {
    let left = buf.len() - at;
    if left < 9 {
        return Err(format!(
            "the file ends {left} bytes into a record's 9-byte header (cut short)"
        ));
    }
    let op = buf[at];
    let len = u64::from_le_bytes(buf[at + 1..at + 9].try_into().unwrap_or([0; 8]));
    if len > (left - 9) as u64 {
        return Err(format!(
            "a record (opcode 0x{op:02x}) states {len} bytes, but only {} are left in the file (cut short or damaged)",
            left - 9
        ));
    }
    Ok((op, &buf[at + 9..at + 9 + len as usize]))
}

/// A chunk, decompressed.
struct Chunk {
    /// Its records.
    records: Vec<u8>,
    /// The (start, end) log times its header states.
    span: (u64, u64),
    /// Whether a CRC vouched for the records.
    crc_checked: bool,
}

/// A chunk's records, decompressed and checked.
fn chunk_items(body: &[u8]) -> Result<Chunk, String> {
    let (header, data) = match mcap::parse_record(OP_CHUNK, body) {
        Ok(Record::Chunk { header, data }) => (header, data),
        Ok(_) => return Err("not a chunk".into()),
        Err(e) => return Err(format!("its header cannot be read ({e})")),
    };
    let span = (header.message_start_time, header.message_end_time);
    let want = header.uncompressed_size;
    if want > MAX_CHUNK_BYTES {
        return Err(format!(
            "the chunk states {want} bytes uncompressed, over the {} MiB a chunk may hold (damaged)",
            MAX_CHUNK_BYTES >> 20
        ));
    }
    let out = match header.compression.as_str() {
        "" => data.to_vec(),
        "zstd" => {
            let dec = zstd::stream::read::Decoder::with_buffer(&data[..])
                .map_err(|e| format!("zstd cannot start ({e})"))?;
            bounded_read(dec, want).map_err(|e| format!("zstd: {e}"))?
        }
        "lz4" => {
            let dec =
                lz4::Decoder::new(&data[..]).map_err(|e| format!("lz4 cannot start ({e})"))?;
            bounded_read(dec, want).map_err(|e| format!("lz4: {e}"))?
        }
        other => {
            return Err(format!(
                "compression '{other}' is not read (zstd, lz4 or none)"
            ))
        }
    };
    if out.len() as u64 != want {
        return Err(format!(
            "it decompresses to {}{} bytes, but states {want}",
            if out.len() as u64 > want {
                "more than "
            } else {
                ""
            },
            out.len().min(want as usize)
        ));
    }
    if header.uncompressed_crc != 0 {
        let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&out);
        if crc != header.uncompressed_crc {
            return Err(format!(
                "its CRC is 0x{crc:08x}, but it states 0x{:08x}",
                header.uncompressed_crc
            ));
        }
    }
    Ok(Chunk {
        records: out,
        span,
        crc_checked: header.uncompressed_crc != 0,
    })
}

/// Every message of a chunk lies within the log times its header states.
fn agrees_with_its_span(items: &[Item<'_>], (start, end): (u64, u64)) -> Result<(), String> {
    for i in items {
        if let Item::Message { log_time_ns, .. } = i {
            if *log_time_ns < start || *log_time_ns > end {
                return Err(format!(
                    "a message logged at {log_time_ns} ns lies outside the chunk's stated span {start}..{end} ns (damaged)"
                ));
            }
        }
    }
    Ok(())
}

/// A chunk without a CRC (the `rosbags` writer and others leave it 0) is checked against
/// the message index records that follow it, where there are any: each channel's message
/// count must agree, else a changed byte inside the compressed data went unseen (a zstd
/// frame need not carry a checksum).
fn agrees_with_its_index(items: &[Item<'_>], buf: &[u8], mut at: usize) -> Result<(), String> {
    let mut indexed: BTreeMap<u16, usize> = BTreeMap::new();
    while let Ok((OP_MESSAGE_INDEX, body)) = frame(buf, at) {
        if let Ok(Record::MessageIndex(ix)) = mcap::parse_record(OP_MESSAGE_INDEX, body) {
            *indexed.entry(ix.channel_id).or_default() += ix.records.len();
        }
        at += 9 + body.len();
    }
    if indexed.is_empty() {
        return Ok(());
    }
    let mut found: BTreeMap<u16, usize> = BTreeMap::new();
    for i in items {
        if let Item::Message { channel_id, .. } = i {
            *found.entry(*channel_id).or_default() += 1;
        }
    }
    indexed.retain(|_, n| *n > 0);
    if found != indexed {
        return Err(format!(
            "its messages per channel {found:?} disagree with its message index {indexed:?} (damaged, and the chunk has no CRC to say where)"
        ));
    }
    Ok(())
}

/// Reads at most `want + 1` bytes (one more than stated, to see an overlong stream),
/// growing the buffer only as output arrives.
fn bounded_read(r: impl Read, want: u64) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::with_capacity(want.min(1 << 20) as usize);
    r.take(want + 1).read_to_end(&mut out)?;
    Ok(out)
}

/// Every record of a decompressed chunk, or what is wrong with the first bad one.
fn parse_all(records: &[u8]) -> Result<Vec<Item<'_>>, String> {
    let mut items = Vec::new();
    let mut at = 0;
    while at < records.len() {
        let (op, body) = frame(records, at).map_err(|e| format!("inside the chunk: {e}"))?;
        if let Some(i) = item(op, body).map_err(|e| format!("inside the chunk: {e}"))? {
            items.push(i);
        }
        at += 9 + body.len();
    }
    Ok(items)
}

/// A schema, channel or message record's body as an [`Item`] (`None` for other records).
fn item(op: u8, body: &[u8]) -> Result<Option<Item<'_>>, String> {
    if !matches!(op, OP_SCHEMA | OP_CHANNEL | OP_MESSAGE) {
        return Ok(None);
    }
    let what = match op {
        OP_SCHEMA => "schema",
        OP_CHANNEL => "channel",
        _ => "message",
    };
    let r = mcap::parse_record(op, body)
        .map_err(|e| format!("a {what} record cannot be read ({e})"))?;
    Ok(match r {
        Record::Schema { header, .. } => Some(Item::Schema {
            id: header.id,
            name: header.name,
        }),
        Record::Channel(c) => Some(Item::Channel {
            id: c.id,
            schema_id: c.schema_id,
            topic: c.topic,
            encoding: c.message_encoding,
        }),
        Record::Message { header, .. } => {
            // The body's header is fixed-size (channel 2, sequence 4, log and publish
            // times 8 + 8): the payload is what follows, borrowed from `body`.
            Some(Item::Message {
                channel_id: header.channel_id,
                log_time_ns: header.log_time,
                data: body.get(22..).unwrap_or(&[]),
            })
        }
        _ => None,
    })
}

/// The stop at a damaged chunk at `at`, with the log times of what is lost where the
/// framing tells them (this chunk's header, and the records after it).
fn stop_at(buf: &[u8], at: usize, message: String, body: &[u8]) -> Stop {
    let own = match mcap::parse_record(OP_CHUNK, body) {
        Ok(Record::Chunk { header, .. }) => {
            Some((header.message_start_time, header.message_end_time))
        }
        _ => None,
    };
    let after = lost_after(buf, at + 9 + body.len());
    let lost_ns = match (own, after) {
        (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
        (a, b) => a.or(b),
    };
    Stop {
        offset: at as u64,
        message,
        lost_ns,
    }
}

/// The earliest and latest log times the records from `at` on state (chunk headers and
/// loose messages), up to the end of the data section or the first broken frame.
fn lost_after(buf: &[u8], mut at: usize) -> Option<(u64, u64)> {
    let mut span: Option<(u64, u64)> = None;
    let mut add = |a: u64, b: u64| {
        span = Some(span.map_or((a, b), |(x, y)| (x.min(a), y.max(b))));
    };
    while at < buf.len() {
        let Ok((op, body)) = frame(buf, at) else {
            break;
        };
        match op {
            OP_FOOTER | OP_DATA_END => break,
            OP_CHUNK => {
                if let Ok(Record::Chunk { header, .. }) = mcap::parse_record(OP_CHUNK, body) {
                    add(header.message_start_time, header.message_end_time);
                }
            }
            OP_MESSAGE => {
                if let Ok(Some(Item::Message { log_time_ns, .. })) = item(op, body) {
                    add(log_time_ns, log_time_ns);
                }
            }
            _ => {}
        }
        at += 9 + body.len();
    }
    span
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(op: u8, body: &[u8]) -> Vec<u8> {
        let mut v = vec![op];
        v.extend_from_slice(&(body.len() as u64).to_le_bytes());
        v.extend_from_slice(body);
        v
    }

    fn message(channel: u16, t: u64, payload: &[u8]) -> Vec<u8> {
        let mut b = channel.to_le_bytes().to_vec();
        b.extend_from_slice(&7u32.to_le_bytes());
        b.extend_from_slice(&t.to_le_bytes());
        b.extend_from_slice(&t.to_le_bytes());
        b.extend_from_slice(payload);
        record(OP_MESSAGE, &b)
    }

    fn items(buf: &[u8]) -> (Vec<String>, Option<Stop>) {
        let mut seen = Vec::new();
        let stop = walk(buf, &mut |i| seen.push(format!("{i:?}"))).unwrap();
        (seen, stop)
    }

    #[test]
    fn loose_messages_are_read_and_a_cut_record_stops_at_its_offset() {
        let mut f = MAGIC.to_vec();
        f.extend(message(1, 10, b"abc"));
        let second = f.len();
        f.extend(message(1, 20, b"de"));
        let (seen, stop) = items(&f);
        assert_eq!(seen.len(), 2);
        assert!(seen[1].contains("log_time_ns: 20") && seen[1].contains("[100, 101]"));
        assert!(stop.is_none());
        // Cut the second record short: the first is kept, the stop names the second.
        let (seen, stop) = items(&f[..f.len() - 1]);
        assert_eq!(seen.len(), 1);
        let stop = stop.unwrap();
        assert_eq!(stop.offset, second as u64);
        assert!(stop.message.contains("cut short"), "{}", stop.message);
    }

    #[test]
    fn a_stated_length_past_the_file_is_damage_not_an_allocation() {
        let mut f = MAGIC.to_vec();
        let mut r = message(1, 10, b"abc");
        r[1..9].copy_from_slice(&u64::MAX.to_le_bytes());
        f.extend(r);
        let (seen, stop) = items(&f);
        assert!(seen.is_empty());
        assert!(stop.unwrap().message.contains(&u64::MAX.to_string()));
    }

    #[test]
    fn not_an_mcap_file_is_said() {
        assert!(walk(b"hello world", &mut |_| {})
            .unwrap_err()
            .contains("magic"));
    }
}
