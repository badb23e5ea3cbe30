//! Merging the messages of one topic into samples.
//!
//! Messages of a topic are sorted by time; messages with the same time and disjoint joint
//! subsets (several publishers) merge into one sample. A joint given twice at the same time,
//! or whose time goes backwards in file order on one channel, is an error. The joint order is
//! the first message's, then joints first seen later, in order of appearance.
//!
//! Time is integer nanoseconds throughout: a message's header stamp, or its log time when
//! every stamp of the topic is zero (or the type has no header).

use std::collections::HashMap;

use super::scan::Location;

/// One message as the reader extracted it: joint names and up to three columns (`values[0]`
/// required: positions, or efforts for the effort roles; then velocities and efforts).
pub(crate) struct Extracted {
    /// Header stamp [ns], if the type has a header.
    pub stamp: Option<i64>,
    /// Joint names, aligned with the columns.
    pub names: Vec<String>,
    /// The columns (empty ones mean "not in this message").
    pub values: [Vec<f64>; 3],
}

/// The messages of one topic as read: joint names interned, values in flat arrays, so a long
/// bag costs about what the run itself costs.
pub(crate) struct TopicData {
    /// Column names in messages, plural and singular (e.g. `positions`, `position`).
    columns: [(&'static str, &'static str); 3],
    /// Topic of the states, for messages about joints not in them.
    states_topic: String,
    names: Vec<String>,
    index: HashMap<String, u32>,
    msgs: Vec<MsgRef>,
    ids: Vec<u32>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
    any_stamp: bool,
}

/// One message: its times and its slice of the flat arrays.
struct MsgRef {
    stamp: i64,
    log: i64,
    channel: u32,
    start: usize,
    len: usize,
    has_velocity: bool,
    has_effort: bool,
    /// Where its record is in the file.
    at: Location,
}

/// A topic merged into samples.
pub(crate) struct Merged {
    /// Joint names, the column order.
    pub joints: Vec<String>,
    /// Sample times [ns].
    pub t: Vec<i64>,
    /// First column (always there).
    pub position: Vec<f64>,
    /// Second column, when any message had it.
    pub velocity: Option<Vec<f64>>,
    /// Third column, when any message had it.
    pub effort: Option<Vec<f64>>,
}

impl TopicData {
    /// An empty topic whose columns are named `columns` (plural, singular) in messages.
    pub(crate) fn new(columns: [(&'static str, &'static str); 3], states_topic: &str) -> TopicData {
        TopicData {
            columns,
            states_topic: states_topic.to_string(),
            names: Vec::new(),
            index: HashMap::new(),
            msgs: Vec::new(),
            ids: Vec::new(),
            position: Vec::new(),
            velocity: Vec::new(),
            effort: Vec::new(),
            any_stamp: false,
        }
    }

    /// Number of messages stored.
    pub(crate) fn len(&self) -> usize {
        self.msgs.len()
    }

    /// Checks and stores a message: array lengths and finite values.
    pub(crate) fn push(&mut self, topic: &str, m: Extracted, log_ns: i64, channel: u32, at: Location) -> std::result::Result<(), String> {
        let stamp = m.stamp.unwrap_or(0);
        let t = ns_to_seconds(if stamp != 0 { stamp } else { log_ns });
        let [c0, c1, c2] = self.columns;
        // array lengths
        if m.names.is_empty() {
            return Err(format!("{topic} message at t = {t} s has no joint names"));
        }
        if m.values[0].len() != m.names.len() {
            return Err(format!("{topic} message at t = {t} s has {} {} for {} joints", m.values[0].len(), c0.0, m.names.len()));
        }
        for ((what, _), v) in [(c1, &m.values[1]), (c2, &m.values[2])] {
            if !v.is_empty() && v.len() != m.names.len() {
                return Err(format!("{topic} message at t = {t} s has {} {what} for {} joints", v.len(), m.names.len()));
            }
        }
        // finite values
        for (i, j) in m.names.iter().enumerate() {
            for ((_, what), v) in [(c0, &m.values[0]), (c1, &m.values[1]), (c2, &m.values[2])] {
                if let Some(x) = v.get(i).filter(|x| !x.is_finite()) {
                    return Err(format!("{topic}: {what} of joint '{j}' is {x} at t = {t} s"));
                }
            }
        }
        if self.index.len() + m.names.len() > u32::MAX as usize / 2 {
            return Err(format!("{topic}: too many joint names"));
        }
        let [position, velocity, effort] = m.values;
        // store
        let start = self.ids.len();
        for j in &m.names {
            let id = match self.index.get(j) {
                Some(&id) => id,
                None => {
                    self.names.push(j.clone());
                    self.index.insert(j.clone(), (self.names.len() - 1) as u32);
                    (self.names.len() - 1) as u32
                }
            };
            self.ids.push(id);
        }
        let n = m.names.len();
        self.position.extend_from_slice(&position);
        let has_velocity = !velocity.is_empty();
        let has_effort = !effort.is_empty();
        if has_velocity {
            self.velocity.extend_from_slice(&velocity);
        } else {
            self.velocity.extend(std::iter::repeat_n(0.0, n));
        }
        if has_effort {
            self.effort.extend_from_slice(&effort);
        } else {
            self.effort.extend(std::iter::repeat_n(0.0, n));
        }
        self.any_stamp |= stamp != 0;
        self.msgs.push(MsgRef { stamp, log: log_ns, channel, start, len: n, has_velocity, has_effort, at });
        Ok(())
    }

    /// Merges messages into samples (see the module docs); `joints` fixes the joint set.
    pub(crate) fn merge(self, topic: &str, joints: Option<&[String]>) -> std::result::Result<Merged, String> {
        let times: Vec<i64> = self.msgs.iter().map(|m| if self.any_stamp { m.stamp } else { m.log }).collect();
        let time_s = ns_to_seconds;

        // columns: the given joints, or the order of first appearance (first message first)
        let (names, column): (Vec<String>, Vec<usize>) = match joints {
            Some(js) => {
                let mut column = Vec::with_capacity(self.names.len());
                for (id, j) in self.names.iter().enumerate() {
                    let Some(c) = js.iter().position(|x| x == j) else {
                        let first = self.msgs.iter().find(|m| self.ids[m.start..m.start + m.len].contains(&(id as u32)));
                        let at = first.map(|m| format!("; it is first in the {}", m.at)).unwrap_or_default();
                        return Err(format!("joint '{j}' is in {topic} but not in {} (joints: {}){at}", self.states_topic, js.join(", ")));
                    };
                    column.push(c);
                }
                (js.to_vec(), column)
            }
            None => (self.names.clone(), (0..self.names.len()).collect()),
        };

        // time strictly increasing per joint and channel (publisher), in file order
        let mut last_time: HashMap<(u32, u32), i64> = HashMap::new();
        for (m, &t) in self.msgs.iter().zip(&times) {
            for &id in &self.ids[m.start..m.start + m.len] {
                if let Some(prev) = last_time.insert((m.channel, id), t) {
                    let j = &self.names[id as usize];
                    if t == prev {
                        return Err(format!("{}: {topic}: joint '{j}' is given twice at the same time t = {} s", m.at, time_s(t)));
                    }
                    if t < prev {
                        return Err(format!("{}: {topic}: time is not monotonic for joint '{j}': t = {} s comes after t = {} s", m.at, time_s(t), time_s(prev)));
                    }
                }
            }
        }

        // group by time; messages with the same time merge
        let dof = names.len();
        let mut order: Vec<usize> = (0..self.msgs.len()).collect();
        order.sort_by_key(|&i| times[i]);
        let has_velocity = self.msgs.iter().any(|m| m.has_velocity);
        let has_effort = self.msgs.iter().any(|m| m.has_effort);
        let mut out = Merged { joints: names.clone(), t: Vec::new(), position: Vec::new(), velocity: None, effort: None };
        let mut velocity = Vec::new();
        let mut effort = Vec::new();
        let mut filled = vec![false; dof];
        let mut g = 0;
        while g < order.len() {
            let t = times[order[g]];
            let row = out.position.len();
            out.position.resize(row + dof, 0.0);
            velocity.resize(row + dof, 0.0);
            effort.resize(row + dof, 0.0);
            filled.fill(false);
            while g < order.len() && times[order[g]] == t {
                let m = &self.msgs[order[g]];
                for (what, any, this) in [(self.columns[1].1, has_velocity, m.has_velocity), (self.columns[2].1, has_effort, m.has_effort)] {
                    if any && !this {
                        return Err(format!("{}: {topic}: the message at t = {} s has no {what} while other messages have one", m.at, time_s(t)));
                    }
                }
                for i in m.start..m.start + m.len {
                    let id = self.ids[i] as usize;
                    let k = column[id];
                    if filled[k] {
                        return Err(format!("{}: {topic}: joint '{}' is given twice at the same time t = {} s", m.at, self.names[id], time_s(t)));
                    }
                    filled[k] = true;
                    out.position[row + k] = self.position[i];
                    velocity[row + k] = self.velocity[i];
                    effort[row + k] = self.effort[i];
                }
                g += 1;
            }
            if let Some(k) = filled.iter().position(|f| !f) {
                let at = self.msgs[order[g - 1]].at;
                return Err(format!("{at}: {topic}: joint '{}' is missing at t = {} s (no message with that joint has this time stamp)", names[k], time_s(t)));
            }
            out.t.push(t);
        }
        out.velocity = has_velocity.then_some(velocity);
        out.effort = has_effort.then_some(effort);
        Ok(out)
    }
}

/// Nanoseconds as seconds (for messages).
pub(crate) fn ns_to_seconds(ns: i64) -> f64 {
    ns.div_euclid(1_000_000_000) as f64 + ns.rem_euclid(1_000_000_000) as f64 / 1e9
}
