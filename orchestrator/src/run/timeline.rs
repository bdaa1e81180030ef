//! What the pool records of its workers for the run's timeline (`store::timeline`): each case
//! on a lane (a row of the figure: one case at a time, on one node), each lane's idle spans
//! within a batch, and the batches. A lane is taken by a starting case and given back when its
//! record is stored; the lowest free lane of the node is taken, so lanes are as many as cases
//! ever ran side by side there.
//!
//! The timeline is a diagnosis, not a result: a failure to write it is said once and the run
//! goes on without it. Its file is made when the first case starts, so a run that finds
//! everything stored leaves none (and `status --timeline` still shows the run that worked).

use crate::store::timeline::{Event, Phases, Writer};
use crate::store::{FileError, Store};

/// Seconds since the epoch now.
pub fn now_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

struct Lane {
    node: usize,
    busy: bool,
    /// When it was given back (or its batch began).
    free_since: f64,
}

/// A run's timeline as its pool goes (neither a file to make nor a writer: not recorded, as for
/// `compare`'s runs).
#[derive(Default)]
pub struct Timeline {
    /// The folder and run id of the file, until the first case makes it.
    file: Option<(std::path::PathBuf, String)>,
    writer: Option<Writer>,
    node_names: Vec<String>,
    lanes: Vec<Lane>,
    batch_begin: f64,
}

/// A case's place on the timeline while it runs.
#[derive(Clone, Copy)]
pub struct OnLane {
    pub lane: usize,
    pub started: f64,
    pub fresh: bool,
}

impl Timeline {
    /// Records into `results/<study>/timeline/<run_id>.jsonl`, made when the first case starts;
    /// where it cannot be made the run goes on unrecorded, with a warning.
    pub fn recorded(store: &Store, run_id: &str) -> Timeline {
        Timeline {
            file: Some((crate::store::timeline::dir(store), run_id.to_string())),
            ..Timeline::default()
        }
    }

    /// A batch begins on nodes named `node_names`: the free lanes are idle from now on.
    pub fn begin_batch(&mut self, node_names: Vec<String>) {
        self.node_names = node_names;
        self.batch_begin = now_s();
        for lane in &mut self.lanes {
            lane.free_since = self.batch_begin;
        }
    }

    /// Takes the lowest free lane of `node` for a case starting now (`fresh`: on a worker or
    /// process started for it); its idle span since it was last free is recorded.
    pub fn take(&mut self, node: usize, fresh: bool) -> OnLane {
        if let Some((dir, run_id)) = self.file.take() {
            self.writer = Writer::create(&dir, &run_id)
                .inspect_err(|e| log::warn!("no timeline of this run: {e}"))
                .ok();
        }
        let started = now_s();
        let free = self.lanes.iter().position(|l| l.node == node && !l.busy);
        let lane = free.unwrap_or_else(|| {
            self.lanes.push(Lane {
                node,
                busy: false,
                free_since: self.batch_begin,
            });
            self.lanes.len() - 1
        });
        let from = self.lanes[lane].free_since;
        self.lanes[lane].busy = true;
        self.idle(lane, from, started);
        OnLane {
            lane,
            started,
            fresh,
        }
    }

    /// Gives `on`'s lane back: its case (`key`) was answered at `answered` and is stored now,
    /// with the solver's `phases` where it ran.
    pub fn give_back(&mut self, on: OnLane, key: &str, answered: f64, phases: Option<Phases>) {
        let saved = now_s();
        self.lanes[on.lane].busy = false;
        self.lanes[on.lane].free_since = saved;
        let event = Event::Case {
            node: self.node_name(on.lane),
            lane: self.lane_on_node(on.lane),
            key: key.to_string(),
            started: on.started,
            answered,
            saved,
            fresh: on.fresh,
            phases,
        };
        self.write(&event);
    }

    /// The batch ends: the free lanes were idle to now.
    pub fn end_batch(&mut self) {
        let end = now_s();
        for lane in 0..self.lanes.len() {
            if !self.lanes[lane].busy {
                self.idle(lane, self.lanes[lane].free_since, end);
            }
        }
        let begin = self.batch_begin;
        self.write(&Event::Batch { begin, end });
        if let Some(Err(e)) = self.writer.as_mut().map(Writer::flush) {
            self.stop_recording(e);
        }
    }

    fn idle(&mut self, lane: usize, from: f64, to: f64) {
        if to > from {
            let event = Event::Idle {
                node: self.node_name(lane),
                lane: self.lane_on_node(lane),
                from,
                to,
            };
            self.write(&event);
        }
    }

    fn node_name(&self, lane: usize) -> String {
        let node = self.lanes[lane].node;
        self.node_names
            .get(node)
            .cloned()
            .unwrap_or_else(|| format!("node {node}"))
    }

    /// A lane's number among its node's.
    fn lane_on_node(&self, lane: usize) -> usize {
        let node = self.lanes[lane].node;
        self.lanes[..lane].iter().filter(|l| l.node == node).count()
    }

    fn write(&mut self, event: &Event) {
        if let Some(Err(e)) = self.writer.as_mut().map(|w| w.write(event)) {
            self.stop_recording(e);
        }
    }

    fn stop_recording(&mut self, e: FileError) {
        log::warn!("the timeline of this run stops here: {e}");
        self.writer = None;
    }
}
