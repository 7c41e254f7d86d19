//! Reading a rosbag2 folder (`metadata.yaml` beside its `.mcap` files) or one `.mcap`
//! file with the `mcap` crate: the topics it holds and the raw messages of the topics
//! asked for.
//!
//! The data section is read record by record ([`crate::records`]), every stated length
//! bounded; the summary (chunk index) is not needed, so a damaged index loses nothing. A
//! damaged file is read up to the damage, whose byte offset is named: what came before is
//! kept, and [`Bag::damage`] says where reading stopped and what span was lost.

use crate::error::ImportError;
use crate::records::{self, Item};
use serde::Deserialize;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};

/// A topic in the bag.
#[derive(Debug, Clone, PartialEq)]
pub struct Topic {
    /// Topic name, e.g. `/joint_states`.
    pub name: String,
    /// ROS message type, e.g. `sensor_msgs/msg/JointState` (the channel's schema name).
    pub msg_type: String,
    /// Message encoding; rosbag2 writes `cdr`.
    pub encoding: String,
    /// Messages read on this topic.
    pub count: usize,
}

/// One message as stored.
#[derive(Debug, Clone, PartialEq)]
pub struct RawMessage {
    /// When the recorder received it (MCAP log time), ns since the Unix epoch.
    pub log_time_ns: u64,
    /// The serialised message (CDR with its 4-byte encapsulation header).
    pub data: Vec<u8>,
}

/// Where reading stopped early.
#[derive(Debug, Clone, PartialEq)]
pub struct Damage {
    /// The `.mcap` file.
    pub file: PathBuf,
    /// Byte offset of the chunk (or record) that could not be read, when known.
    pub offset: Option<u64>,
    /// What the `mcap` crate said.
    pub message: String,
    /// Messages read before it (all topics).
    pub messages_before: usize,
    /// Log times (ns since the epoch) of the first and last message lost, where the
    /// records after the damage still tell them.
    pub lost_ns: Option<(u64, u64)>,
}

impl Damage {
    /// The lost span in seconds after `t0_ns` (the bag's first message), when known and
    /// plausible (a damaged header can state any time).
    pub fn lost_span_s(&self, t0_ns: u64) -> Option<(f64, f64)> {
        let (a, b) = self.lost_ns?;
        let s = |t: u64| t.checked_sub(t0_ns).map(|d| d as f64 * 1e-9);
        match (s(a), s(b)) {
            (Some(a), Some(b)) if a <= b && b < 1e7 => Some((a, b)),
            _ => None,
        }
    }
}

impl std::fmt::Display for Damage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.offset {
            Some(o) => write!(
                f,
                "{}: the record at byte offset {o} cannot be read ({}); {} messages before it were read",
                self.file.display(),
                self.message,
                self.messages_before
            ),
            None => write!(
                f,
                "{}: {}; {} messages were read",
                self.file.display(),
                self.message,
                self.messages_before
            ),
        }
    }
}

/// A bag: its topics and the messages of the wanted topics, in file order.
#[derive(Debug, Clone, Default)]
pub struct Bag {
    /// What was opened (folder or file).
    pub path: PathBuf,
    /// Its `.mcap` files, in order.
    pub files: Vec<PathBuf>,
    /// Every topic of every file.
    pub topics: Vec<Topic>,
    /// Messages of the wanted topics.
    pub messages: BTreeMap<String, Vec<RawMessage>>,
    /// Where reading stopped early, if it did.
    pub damage: Option<Damage>,
}

#[derive(Deserialize)]
struct Metadata {
    rosbag2_bagfile_information: Info,
}

#[derive(Deserialize)]
struct Info {
    storage_identifier: String,
    relative_file_paths: Vec<String>,
    #[serde(default)]
    compression_mode: Option<String>,
}

impl Bag {
    /// Opens a rosbag2 folder or an `.mcap` file, keeping the messages of `wanted` topics
    /// (all topics are listed).
    pub fn open(path: &Path, wanted: &[&str]) -> Result<Bag, ImportError> {
        let files = bag_files(path)?;
        let mut bag = Bag {
            path: path.to_path_buf(),
            files: files.clone(),
            ..Bag::default()
        };
        let wanted: HashSet<&str> = wanted.iter().copied().collect();
        for f in &files {
            let buf = std::fs::read(f)
                .map_err(|e| ImportError::new(f, format!("cannot be read: {e}")))?;
            read_file(f, &buf, &wanted, &mut bag)?;
            if bag.damage.is_some() {
                break;
            }
        }
        Ok(bag)
    }

    /// The topic called `name`.
    pub fn topic(&self, name: &str) -> Option<&Topic> {
        self.topics.iter().find(|t| t.name == name)
    }

    /// Every topic as `name (type, N messages)`, one per line, for error messages.
    pub fn describe_topics(&self) -> String {
        if self.topics.is_empty() {
            return "  (no topics)".into();
        }
        self.topics
            .iter()
            .map(|t| format!("  {} ({}, {} messages)", t.name, t.msg_type, t.count))
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// Topics of one of `types`.
    pub fn topics_of(&self, types: &[&str]) -> Vec<&Topic> {
        self.topics
            .iter()
            .filter(|t| types.contains(&t.msg_type.as_str()))
            .collect()
    }

    /// Messages counted so far, every topic.
    fn message_count(&self) -> usize {
        self.topics.iter().map(|t| t.count).sum()
    }

    fn count(&mut self, topic: &str, msg_type: &str, encoding: &str) {
        match self.topics.iter_mut().find(|t| t.name == topic) {
            Some(t) => t.count += 1,
            None => self.topics.push(Topic {
                name: topic.to_string(),
                msg_type: msg_type.to_string(),
                encoding: encoding.to_string(),
                count: 1,
            }),
        }
    }

    fn declare(&mut self, topic: &str, msg_type: &str, encoding: &str) {
        if self.topic(topic).is_none() {
            self.topics.push(Topic {
                name: topic.to_string(),
                msg_type: msg_type.to_string(),
                encoding: encoding.to_string(),
                count: 0,
            });
        }
    }
}

/// The largest `metadata.yaml` read: rosbag2 writes a few kilobytes (one entry per file
/// and topic); 1 MiB leaves room for thousands of topics.
pub const MAX_METADATA_BYTES: u64 = 1 << 20;

/// The `.mcap` files of a bag folder (from its metadata.yaml) or the file itself.
fn bag_files(path: &Path) -> Result<Vec<PathBuf>, ImportError> {
    if path.is_file() {
        return Ok(vec![path.to_path_buf()]);
    }
    if !path.is_dir() {
        return Err(ImportError::new(
            path,
            "no such bag: give a rosbag2 folder (with metadata.yaml) or an .mcap file",
        ));
    }
    let meta = path.join("metadata.yaml");
    if !meta.is_file() {
        let mcaps: Vec<String> = std::fs::read_dir(path)
            .map(|d| {
                d.filter_map(|e| e.ok())
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .filter(|n| n.ends_with(".mcap"))
                    .collect()
            })
            .unwrap_or_default();
        let hint = if mcaps.is_empty() {
            "and no .mcap file".to_string()
        } else {
            format!(
                "(it has {}: give that file instead to import it without the folder's metadata)",
                mcaps.join(", ")
            )
        };
        return Err(ImportError::new(
            path,
            format!("not a rosbag2 folder: no metadata.yaml {hint}"),
        ));
    }
    let size = std::fs::metadata(&meta).map(|m| m.len()).unwrap_or(0);
    if size > MAX_METADATA_BYTES {
        return Err(ImportError::new(
            &meta,
            format!(
                "is {size} bytes; a rosbag2 metadata file is a few kilobytes (at most {} MiB is read)",
                MAX_METADATA_BYTES >> 20
            ),
        ));
    }
    let text = std::fs::read_to_string(&meta)
        .map_err(|e| ImportError::new(&meta, format!("cannot be read: {e}")))?;
    let m: Metadata = serde_yaml::from_str(&text).map_err(|e| {
        let at = e
            .location()
            .map(|l| format!(":{}:{}", l.line(), l.column()))
            .unwrap_or_default();
        ImportError::new(
            format!("{}{at}", meta.display()),
            format!("not a rosbag2 metadata file: {e}"),
        )
    })?;
    let info = m.rosbag2_bagfile_information;
    if info.storage_identifier != "mcap" {
        return Err(ImportError::new(
            &meta,
            format!(
                "storage '{}' is not read, only mcap (the default since ROS 2 Iron); convert the bag with `ros2 bag convert -i {} -o out.yaml` where out.yaml says `storage_id: mcap`",
                info.storage_identifier,
                path.display()
            ),
        ));
    }
    if info
        .compression_mode
        .as_deref()
        .unwrap_or("")
        .eq_ignore_ascii_case("file")
    {
        return Err(ImportError::new(
            &meta,
            "the bag's files are compressed whole (compression_mode FILE): decompress them first (`ros2 bag decompress`), or record with MCAP chunk compression instead",
        ));
    }
    let files: Vec<PathBuf> = info
        .relative_file_paths
        .iter()
        .map(|f| path.join(f))
        .collect();
    if files.is_empty() {
        return Err(ImportError::new(
            &meta,
            "lists no files (relative_file_paths is empty)",
        ));
    }
    let mut seen = HashSet::new();
    for f in &info.relative_file_paths {
        if !seen.insert(f.as_str()) {
            return Err(ImportError::new(
                &meta,
                format!("lists {f} more than once (relative_file_paths): a damaged metadata file"),
            ));
        }
    }
    for f in &files {
        if !f.is_file() {
            return Err(ImportError::new(
                &meta,
                format!("lists {} but the folder has no such file", f.display()),
            ));
        }
    }
    Ok(files)
}

/// Reads one `.mcap` file's data section ([`records::walk`]): every channel is declared,
/// every message counted and the wanted ones kept; damage is noted in `bag.damage`.
fn read_file(
    file: &Path,
    buf: &[u8],
    wanted: &HashSet<&str>,
    bag: &mut Bag,
) -> Result<(), ImportError> {
    let before = bag.message_count();
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut channels: HashMap<u16, (String, String, String)> = HashMap::new();
    let mut unknown: Option<u16> = None;
    let stop = records::walk(buf, &mut |item| match item {
        Item::Schema { id, name } => {
            schemas.insert(id, name);
        }
        Item::Channel {
            id,
            schema_id,
            topic,
            encoding,
        } => {
            let ty = schemas
                .get(&schema_id)
                .cloned()
                .unwrap_or_else(|| "(no schema)".into());
            bag.declare(&topic, &ty, &encoding);
            channels.insert(id, (topic, ty, encoding));
        }
        Item::Message {
            channel_id,
            log_time_ns,
            data,
        } => match channels.get(&channel_id) {
            Some((topic, ty, encoding)) => {
                bag.count(topic, ty, encoding);
                if wanted.contains(topic.as_str()) {
                    bag.messages
                        .entry(topic.clone())
                        .or_default()
                        .push(RawMessage {
                            log_time_ns,
                            data: data.to_vec(),
                        });
                }
            }
            None => {
                unknown.get_or_insert(channel_id);
            }
        },
    })
    .map_err(|e| ImportError::new(file, e))?;
    if let Some(s) = stop {
        bag.damage = Some(Damage {
            file: file.to_path_buf(),
            offset: Some(s.offset),
            message: s.message,
            messages_before: bag.message_count() - before,
            lost_ns: s.lost_ns,
        });
    } else if let Some(id) = unknown {
        // A message on a channel no record declared: its channel record was damaged.
        bag.damage = Some(Damage {
            file: file.to_path_buf(),
            offset: None,
            message: format!("messages on channel {id}, which no channel record declares (a damaged channel record, or a damaged message header)"),
            messages_before: bag.message_count() - before,
            lost_ns: None,
        });
    }
    Ok(())
}
