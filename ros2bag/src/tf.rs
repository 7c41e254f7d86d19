//! The pose of one frame in another from the tf tree: transforms on the dynamic topic
//! (`/tf`) and the static one (`/tf_static`), chained along the tree's path between the
//! two frames (edges walked backwards are inverted).
//!
//! Samples are taken at the stamps of the chain's sparsest dynamic edge; every other
//! dynamic edge is interpolated there (translation linearly, rotation by slerp) and a
//! sample outside another edge's time span is dropped, never extrapolated.

use crate::bag::Bag;
use crate::error::ImportError;
use crate::messages::{decode, unit, TFMessage};
use nalgebra::{Isometry3, Translation3};
use std::collections::{BTreeMap, VecDeque};

/// One edge of the tree: parent -> child transforms over time.
#[derive(Debug, Clone, Default)]
struct Edge {
    is_static: bool,
    samples: Vec<(i64, Isometry3<f64>)>,
}

fn read_edges(
    bag: &Bag,
    topic: &str,
    is_static: bool,
    use_receive_time: bool,
    edges: &mut BTreeMap<(String, String), Edge>,
) -> Result<(), ImportError> {
    for (k, m) in bag
        .messages
        .get(topic)
        .map(Vec::as_slice)
        .unwrap_or(&[])
        .iter()
        .enumerate()
    {
        let tf: TFMessage = decode(&m.data).map_err(|e| {
            ImportError::new(
                &bag.path,
                format!("{topic}: message {k} cannot be decoded: {e}"),
            )
        })?;
        for t in tf.transforms {
            let parent = t.header.frame_id.trim_start_matches('/').to_string();
            let child = t.child_frame_id.trim_start_matches('/').to_string();
            let stamp = if use_receive_time {
                m.log_time_ns as i64
            } else {
                t.header.stamp.ns()
            };
            let tr = t.transform.translation;
            let iso = Isometry3::from_parts(
                Translation3::new(tr.x, tr.y, tr.z),
                unit(&t.transform.rotation),
            );
            let e = edges.entry((parent, child)).or_default();
            e.is_static |= is_static;
            e.samples.push((stamp, iso));
        }
    }
    Ok(())
}

/// The edge's transform at `t`: a static edge's latest value; a dynamic edge's value
/// interpolated between the samples around `t`, `None` outside them.
fn at(e: &Edge, t: i64) -> Option<Isometry3<f64>> {
    if e.is_static {
        return e.samples.last().map(|s| s.1);
    }
    let s = &e.samples;
    let i = s.partition_point(|p| p.0 < t);
    if i < s.len() && s[i].0 == t {
        return Some(s[i].1);
    }
    if i == 0 || i == s.len() {
        return None;
    }
    let (a, b) = (&s[i - 1], &s[i]);
    let w = (t - a.0) as f64 / (b.0 - a.0) as f64;
    Some(a.1.lerp_slerp(&b.1, w))
}

/// Samples of the pose of `base` in `fixed`, from the tf topics of `bag`.
pub fn chain(
    bag: &Bag,
    topic: &str,
    static_topic: &str,
    fixed: &str,
    base: &str,
    use_receive_time: bool,
) -> Result<Vec<(i64, Isometry3<f64>)>, ImportError> {
    let mut edges = BTreeMap::new();
    read_edges(bag, topic, false, use_receive_time, &mut edges)?;
    read_edges(bag, static_topic, true, use_receive_time, &mut edges)?;
    for e in edges.values_mut() {
        e.samples.sort_by_key(|s| s.0);
        e.samples.dedup_by_key(|s| s.0);
    }
    let describe = || {
        edges
            .iter()
            .map(|((p, c), e)| {
                if e.is_static {
                    format!("  {p} -> {c} (static)")
                } else {
                    format!("  {p} -> {c} ({} transforms)", e.samples.len())
                }
            })
            .collect::<Vec<_>>()
            .join("\n")
    };
    let (fixed, base) = (fixed.trim_start_matches('/'), base.trim_start_matches('/'));
    // Breadth-first search over the undirected tree: (edge key, walked forward).
    let mut prev: BTreeMap<&str, (&str, (&String, &String), bool)> = BTreeMap::new();
    let mut queue = VecDeque::from([fixed]);
    let mut seen = std::collections::BTreeSet::from([fixed]);
    while let Some(f) = queue.pop_front() {
        if f == base {
            break;
        }
        for (p, c) in edges.keys() {
            let (next, fwd) = if p == f {
                (c.as_str(), true)
            } else if c == f {
                (p.as_str(), false)
            } else {
                continue;
            };
            if seen.insert(next) {
                prev.insert(next, (f, (p, c), fwd));
                queue.push_back(next);
            }
        }
    }
    if !seen.contains(base) || fixed == base {
        return Err(ImportError::new(
            &bag.path,
            format!(
                "tf ({topic}, {static_topic}) has no chain from {fixed} to {base}; its transforms (parent -> child):\n{}",
                describe()
            ),
        ));
    }
    let mut path: Vec<(&Edge, bool)> = Vec::new();
    let mut f = base;
    while f != fixed {
        let (from, (p, c), fwd) = prev[f];
        path.push((&edges[&(p.clone(), c.clone())], fwd));
        f = from;
    }
    path.reverse();
    let Some(driver) = path
        .iter()
        .filter(|(e, _)| !e.is_static)
        .min_by_key(|(e, _)| e.samples.len())
    else {
        return Err(ImportError::new(
            &bag.path,
            format!("tf: the chain from {fixed} to {base} is static: it does not move; its transforms:\n{}", describe()),
        ));
    };
    let mut out = Vec::with_capacity(driver.0.samples.len());
    'samples: for &(t, _) in &driver.0.samples {
        let mut iso = Isometry3::identity();
        for (e, fwd) in &path {
            let Some(x) = at(e, t) else { continue 'samples };
            iso *= if *fwd { x } else { x.inverse() };
        }
        out.push((t, iso));
    }
    Ok(out)
}
