//! Time limits from history: a job's wall time from the stored timings of its points, or of
//! their nearest neighbours in the sweep (the same refinement series, a smaller grid), so a
//! study is neither killed at a guessed limit nor kept waiting in the queue by a huge one.
//!
//! A point's estimate is the median wall time (the whole run's) of its stored runs; without
//! them, the median of its search's stored probes (the point but the field an adaptive study
//! probes); else the median at the largest smaller `n` of its series, scaled to its own `n` by the
//! power law the two largest such grids show (time ∝ n^b), or by n^(dim+2) (an explicit step
//! count at a fixed CFL number) when only one is stored; without those either (a search's next
//! probe, a new value of its field), its cost model's work (`cost::work`) at the median rate
//! of the study's stored points. A job's limit is the sum over its
//! points × `SAFETY`, plus `START_S` for the job (its workers' start, MPI's) and `CASE_S` a case
//! (its hand-off to a worker and its record stored; `START_S` a case over several ranks, which
//! starts MPI of its own), rounded up to the minute and at least `FLOOR_S`.
//! A point stopped at step k of N with a checkpoint resumes there: it counts (N − k)/N of its
//! estimate.

use super::cost::work_of;
use crate::model::resources::WallTime;
use crate::run::plan::Planned;
use crate::statistics::median;
use crate::store::{checkpoint_of, Index, Store, CHECKPOINT};
use schema::record::Status;
use std::collections::HashMap;

/// The margin over the estimate: timings vary between nodes and runs.
pub const SAFETY: f64 = 2.0;
/// Seconds a job, and a case over several ranks, take to start (the processes, MPI's start-up),
/// which the timings leave out.
pub const START_S: f64 = 10.0;
/// Seconds a case on a worker takes beyond its timing: its hand-off and its record stored.
pub const CASE_S: f64 = 1.0;
/// The shortest limit set from history.
pub const FLOOR_S: u64 = 5 * 60;

/// One point's estimated wall time and where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    pub seconds: f64,
    /// Stored runs of the point itself, or the neighbour grids it was scaled from.
    pub from: Source,
}

#[derive(Clone, Debug, PartialEq)]
pub enum Source {
    Itself {
        runs: usize,
    },
    Neighbours {
        n: Vec<u64>,
        exponent: f64,
    },
    /// The stored probes of the same search: the point's fields but the probed one.
    Search {
        runs: usize,
    },
    /// The cost model's work at the study's stored points' median rate.
    Work {
        rate: f64,
    },
}

/// The stored wall times of a study's points, by refinement series and grid.
#[derive(Default)]
pub struct History {
    /// Series → n → wall times of stored ok or diverged runs.
    times: HashMap<String, HashMap<u64, Vec<f64>>>,
    /// Key → the share of its steps a point with a checkpoint has left.
    left: HashMap<String, f64>,
    /// The field an adaptive study probes, and the wall times of its searches' stored probes,
    /// by the point's label without it.
    probed: Option<String>,
    searches: HashMap<String, Vec<f64>>,
    /// Seconds per unit of the cost model's work (`cost::work`) of each timed point: the
    /// rate that turns an untimed point's work into seconds.
    pub rates: Vec<f64>,
}

impl History {
    /// The wall times the store's index holds for the planned points (a point that runs again
    /// because it is stale still has its old timings); `probed`, the field an adaptive study's
    /// searches probe, if it is one.
    pub fn from_index(planned: &[Planned], index: &Index, probed: Option<&str>) -> History {
        let mut times: HashMap<String, HashMap<u64, Vec<f64>>> = HashMap::new();
        let (mut searches, mut rates) = (HashMap::<String, Vec<f64>>::new(), Vec::new());
        for p in planned {
            let Some(stored) = index.stored.get(p.key.as_str()) else {
                continue;
            };
            let measured = matches!(stored.status, Status::Ok | Status::Diverged);
            let (true, Some(wall)) = (measured, stored.wall_s) else {
                continue;
            };
            if let Some(n) = grid(p) {
                let series = times.entry(p.point.series().refinement).or_default();
                series.entry(n).or_default().push(wall);
            }
            if let Some(field) = probed {
                let search = p.point.label_without_field(field);
                searches.entry(search).or_default().push(wall);
            }
            let rate = work_of(p).map(|w| wall / w);
            rates.extend(rate.filter(|r| r.is_finite() && *r > 0.0));
        }
        History {
            times,
            left: HashMap::new(),
            probed: probed.map(str::to_string),
            searches,
            rates,
        }
    }

    /// Counts the checkpoints in `store` of the points to run that the solver of `fingerprint`
    /// resumes: each resumes where it stopped. The work directory is listed once (a submit of
    /// 10⁵ points opens no file per point).
    pub fn resuming(
        mut self,
        store: &Store,
        planned: &[Planned],
        fingerprint: Option<&str>,
    ) -> History {
        let stopped = store.scratch_keys(CHECKPOINT);
        for p in planned
            .iter()
            .filter(|p| p.runs() && stopped.contains(p.key.as_str()))
        {
            let path = store.scratch(&p.key, CHECKPOINT);
            let Ok(case) = &p.case else { continue };
            let ranks = case.ranks();
            let resumed =
                checkpoint_of(&path, &case.canonical(), ranks, fingerprint).and_then(Result::ok);
            if let Some((step, Some(steps))) = resumed.filter(|(_, n)| *n > Some(0)) {
                let left = 1.0 - step.min(steps) as f64 / steps as f64;
                self.left.insert(p.key.to_string(), left);
            }
        }
        self
    }

    /// The estimate for `point`, if it, a probe of its search or a neighbour was timed.
    pub fn estimate(&self, point: &Planned) -> Option<Estimate> {
        let n = grid(point);
        let series = self.times.get(&point.point.series().refinement);
        if let Some(own) = series.zip(n).and_then(|(s, n)| s.get(&n)) {
            return Some(Estimate {
                seconds: median(own),
                from: Source::Itself { runs: own.len() },
            });
        }
        // A search's next probe costs what its earlier ones did: the same operator and case,
        // another value of one field (and the spectrum its first probe measured, shared).
        let search = self
            .probed
            .as_ref()
            .map(|f| point.point.label_without_field(f));
        if let Some(probes) = search.and_then(|s| self.searches.get(&s)) {
            return Some(Estimate {
                seconds: median(probes),
                from: Source::Search { runs: probes.len() },
            });
        }
        let (n, series) = (n?, series?);
        let mut below: Vec<(u64, f64)> = series
            .iter()
            .filter(|(m, _)| **m < n)
            .map(|(m, t)| (*m, median(t)))
            .collect();
        below.sort_by_key(|(m, _)| *m);
        let dim = point.point.get("dim").and_then(|d| d.as_u64()).unwrap_or(1);
        let (n1, t1) = *below.last()?;
        let exponent = match below.len() {
            1 => (dim + 2) as f64,
            k => {
                let (n0, t0) = below[k - 2];
                // A time that fell with the grid (noise at tiny n) says nothing: assume one
                // pass over the points at least.
                ((t1 / t0).ln() / (n1 as f64 / n0 as f64).ln()).max(dim as f64)
            }
        };
        let exponent = if exponent.is_finite() {
            exponent
        } else {
            (dim + 2) as f64
        };
        Some(Estimate {
            seconds: t1 * (n as f64 / n1 as f64).powf(exponent),
            from: Source::Neighbours {
                n: below.iter().rev().take(2).map(|(m, _)| *m).collect(),
                exponent,
            },
        })
    }

    /// The limit of a job running `points` one after another, and a sentence of where it came
    /// from; `None` when a point has no estimate (then the job's limit is the site's or none).
    pub fn limit(&self, points: &[&Planned]) -> Result<(WallTime, String), String> {
        let mut total = START_S;
        let (mut own, mut scaled, mut resumed) = (0, 0, 0);
        let rate = (!self.rates.is_empty()).then(|| median(&self.rates));
        let (mut searched, mut rated) = (0, 0);
        for p in points {
            let by_work = || {
                let seconds = Some(work_of(p)? * rate?).filter(|s| s.is_finite() && *s >= 0.0)?;
                Some(Estimate {
                    seconds,
                    from: Source::Work { rate: rate? },
                })
            };
            let Some(estimate) = self.estimate(p).or_else(by_work) else {
                return Err(format!(
                    "{} has no stored timing, nor a smaller grid of its series, nor a stored point of the study to rate its work",
                    p.point.label()
                ));
            };
            let left = self.left.get(p.key.as_str()).copied().unwrap_or(1.0);
            resumed += usize::from(left < 1.0);
            let ranks = p.case.as_ref().map_or(1, |c| c.ranks());
            let start = if ranks > 1 { START_S } else { CASE_S };
            total += estimate.seconds * left * SAFETY + start;
            match estimate.from {
                Source::Itself { .. } => own += 1,
                Source::Neighbours { .. } => scaled += 1,
                Source::Search { .. } => searched += 1,
                Source::Work { .. } => rated += 1,
            }
        }
        let time = wall_time(total)?;
        let points = |k: usize| match k {
            1 => "1 point".to_string(),
            k => format!("{k} points"),
        };
        let from = match (own, scaled) {
            (o, 0) => format!("the stored timings of {}", points(o)),
            (0, s) => format!("{} scaled from smaller grids", points(s)),
            (o, s) => format!(
                "the stored timings of {}, {} scaled from smaller grids",
                points(o),
                points(s)
            ),
        };
        let from = match (own + scaled, searched) {
            (_, 0) => from,
            (0, s) => format!("{} timed by their searches' stored probes", points(s)),
            (_, s) => format!("{from}, {} by their searches' stored probes", points(s)),
        };
        let from = match (own + scaled + searched, rated) {
            (_, 0) => from,
            (0, r) => format!("{}' work at the study's stored points' rate", points(r)),
            (_, r) => format!("{from}, {}' work at their rate", points(r)),
        };
        let from = match resumed {
            0 => from,
            k => format!(
                "{from} ({} resuming from a checkpoint, only their steps left)",
                points(k)
            ),
        };
        Ok((
            time,
            format!(
                "{from} × {SAFETY}, + {START_S} s for the job and {CASE_S} s a case ({START_S} s over ranks), at least {} min",
                FLOOR_S / 60
            ),
        ))
    }
}

/// A limit of `total` seconds: rounded up to the minute, at least `FLOOR_S`.
pub fn wall_time(total: f64) -> Result<WallTime, String> {
    let minutes = (total / 60.0).ceil();
    let seconds = match minutes.is_finite() && minutes < 1e9 {
        true => (minutes.max(0.0) as u64 * 60).max(FLOOR_S),
        false => u64::MAX,
    };
    WallTime::from_seconds(seconds).ok_or_else(|| {
        let total = schema::text::exact(total);
        format!("the stored timings ask for {total} s, beyond a wall time's 366 days")
    })
}

fn grid(point: &Planned) -> Option<u64> {
    point.point.get("n")?.as_u64()
}

#[cfg(test)]
impl History {
    /// A history of no timings but a rate of seconds per unit of work.
    pub(crate) fn at_rate(seconds_per_work: f64) -> History {
        History {
            rates: vec![seconds_per_work],
            ..History::default()
        }
    }

    /// The wall times `runs` (grid, times) of the refinement series named `series`.
    pub(crate) fn of_series(series: String, runs: &[(u64, &[f64])]) -> History {
        let times = runs.iter().map(|(n, t)| (*n, t.to_vec())).collect();
        History {
            times: HashMap::from([(series, times)]),
            ..History::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run::nlsolve::Checked;
    use crate::run::plan::{Decision, Reason};
    use serde_json::json;

    /// A point of grid `n` on the refinement series `family=<series>`.
    fn point(series: &str, dim: u64, n: u64) -> Planned {
        let study = json!({
            "name": "limits",
            "base": {"dim": dim},
            "sweep": [{"product": {"family": [series], "n": [n]}}],
        });
        let point = crate::kinds::parse(&study.to_string())
            .unwrap()
            .expand()
            .unwrap();
        Planned {
            point: point.into_iter().next().unwrap(),
            case: Err("not checked".into()),
            key: crate::store::case_id_and_key(&format!("{series}-{n}"), "", 0).1,
            case_id: Default::default(),
            decision: Decision::Run(Reason::Missing),
            probe: None,
        }
    }

    fn history(series: &str, runs: &[(u64, &[f64])]) -> History {
        History::of_series(format!("family={series}"), runs)
    }

    #[test]
    fn a_point_is_timed_by_its_own_runs_else_scaled_from_its_series_smaller_grids() {
        let h = history("a", &[(64, &[1.0, 9.0, 2.0]), (128, &[8.0])]);
        let own = h.estimate(&point("a", 1, 64)).unwrap();
        assert_eq!(
            own,
            Estimate {
                seconds: 2.0,
                from: Source::Itself { runs: 3 }
            }
        );
        // 2 s at 64, 8 s at 128: time ∝ n², so 32 s at 256.
        let scaled = h.estimate(&point("a", 1, 256)).unwrap();
        assert!((scaled.seconds - 32.0).abs() < 1e-9, "{scaled:?}");
        assert_eq!(
            scaled.from,
            Source::Neighbours {
                n: vec![128, 64],
                exponent: 2.0
            }
        );
        // One smaller grid in 2D: n^(dim+2) = n⁴.
        let h = history("b", &[(100, &[1.0])]);
        assert!((h.estimate(&point("b", 2, 200)).unwrap().seconds - 16.0).abs() < 1e-9);
        assert_eq!(h.estimate(&point("b", 2, 50)), None, "no smaller grid");
        assert_eq!(h.estimate(&point("c", 2, 200)), None, "another series");
    }

    /// A search's new probe (a value of the probed field not run before) costs the median of
    /// its search's stored probes: the same point but that field; another search's say nothing.
    #[test]
    fn a_searchs_next_probe_is_timed_by_its_stored_probes() {
        let probe = |series: &str, cfl: f64| {
            let mut p = point(series, 1, 64);
            p.point = p.point.with("cfl", cfl.into());
            p
        };
        let search = probe("a", 0.5).point.label_without_field("cfl");
        let h = History {
            probed: Some("cfl".into()),
            searches: HashMap::from([(search, vec![1.0, 9.0, 2.0])]),
            ..History::default()
        };
        assert_eq!(
            h.estimate(&probe("a", 1.25)),
            Some(Estimate {
                seconds: 2.0,
                from: Source::Search { runs: 3 }
            })
        );
        assert_eq!(h.estimate(&probe("b", 1.25)), None, "another search");
        let (time, from) = h.limit(&[&probe("a", 1.25)]).unwrap();
        assert_eq!(time.seconds(), FLOOR_S);
        assert!(
            from.contains("1 point timed by their searches' stored probes"),
            "{from}"
        );
    }

    #[test]
    fn a_jobs_limit_sums_its_points_with_the_margin_rounds_up_and_has_a_floor() {
        let h = history("a", &[(64, &[100.0]), (128, &[400.0])]);
        let (p, q) = (point("a", 1, 64), point("a", 1, 128));
        // (100 + 400) × 2 + 10 s + 2 × 1 s = 1012 s → 17 min.
        let (time, from) = h.limit(&[&p, &q]).unwrap();
        assert_eq!(time.seconds(), 17 * 60);
        assert!(from.contains("the stored timings of 2 points"), "{from}");
        let tiny = history("t", &[(8, &[0.01])]);
        let (time, _) = tiny.limit(&[&point("t", 1, 8)]).unwrap();
        assert_eq!(time.seconds(), FLOOR_S);
        // 567 probes of 0.01 s on a worker: 10 s + 567 × (0.02 + 1) s = 588 s → 10 min (at
        // 10 s a case, as before, 95 min); a case over two ranks starts MPI: 10 s of its own.
        let probes = history("p", &[(64, &[0.01])]);
        let one = point("p", 1, 64);
        let (time, _) = probes.limit(&vec![&one; 567]).unwrap();
        assert_eq!(time.seconds(), 10 * 60);
        let mut ranked = point("p", 1, 64);
        let case = serde_json::json!({"dim": 1, "n": 64, "m": 2, "ranks": 2});
        ranked.case = Ok(Checked::unresolved(&case));
        let (time, _) = probes.limit(&vec![&ranked; 567]).unwrap();
        assert_eq!(time.seconds(), 95 * 60, "10 + 567 × 10.02 s = 5691 s");
        let e = h.limit(&[&p, &point("z", 1, 64)]).unwrap_err();
        assert!(e.contains("no stored timing"), "{e}");
    }

    /// A point with a checkpoint three quarters of the way counts a quarter of its estimate.
    #[test]
    fn a_point_resuming_from_a_checkpoint_counts_only_its_steps_left() {
        let mut h = history("a", &[(64, &[1000.0]), (128, &[4000.0])]);
        let (p, q) = (point("a", 1, 64), point("a", 1, 128));
        h.left.insert(q.key.to_string(), 0.25);
        // 10 + 1000 × 2 + 1 + 4000 × 0.25 × 2 + 1 = 4012 s → 67 min.
        let (time, from) = h.limit(&[&p, &q]).unwrap();
        assert_eq!(time.seconds(), 67 * 60);
        assert!(
            from.contains("(1 point resuming from a checkpoint"),
            "{from}"
        );
    }

    /// `resuming` reads the step of steps from the checkpoint's header, of a checkpoint the
    /// solver would resume from only.
    #[test]
    fn the_share_left_comes_from_the_checkpoints_header() {
        use schema::checkpoint::{write, Header, Identity};
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path(), "limits");
        std::fs::create_dir_all(store.work_dir()).unwrap();
        let canonical = json!({"dim": 1, "n": 64, "m": 2, "t_end": 0.1, "cfl": 0.5, "threads": 2});
        let mut p = point("a", 1, 64);
        p.case = Ok(Checked::unresolved(&canonical));
        let checkpoint = |fingerprint: &str| {
            let header = Header {
                identity: Identity {
                    fingerprint: fingerprint.into(),
                    case: Identity::case_text(&canonical),
                    ranks: 1,
                    rank: 0,
                },
                step: 300,
                steps: Some(400),
                parts: vec![("field".into(), 2)],
            };
            let mut bytes = Vec::new();
            write(&mut bytes, &header, [1.0, 2.0]).unwrap();
            std::fs::write(store.scratch(&p.key, CHECKPOINT), bytes).unwrap();
            history("a", &[]).resuming(&store, std::slice::from_ref(&p), Some("f1"))
        };
        assert_eq!(checkpoint("f1").left.get(p.key.as_str()), Some(&0.25));
        // Another build's checkpoint is not resumed: the point counts whole.
        assert_eq!(checkpoint("f2").left.get(p.key.as_str()), None);
    }
}
