//! A model of the distributed solver's time per step on many ranks, fed by runs measured here
//! (docs/scaling.md): per-node compute rates fitted to one-rank runs, the communication each
//! step makes counted from what the runs record (`traffic.*`), and a latency–bandwidth network.
//!
//! Per step (per CG iteration for steady CG) on P ranks of an n × n grid (N = n² nodes):
//! - compute: the one-rank rate times N/P (the FFT: times W log₂ W, W its padded window's points);
//! - halo: each exchange sends the ghosts' 8 bytes, G/P per rank on average, in k messages:
//!   k α + 8 G/(P β); G = 2mn(p_x − 1) + 2mn(p_y − 1) + πm²(p_x − 1)(p_y − 1) ghosts in all for
//!   p_x × p_y blocks (strips of width m along each cut, quarter discs at the crossings);
//! - reductions: 2⌈log₂ P⌉ α each (recursive doubling of one value);
//! - all-to-alls (the sine transform's transposes): (P − 1) α + 8 (N/P)(1 − 1/P)/β each.
//!
//! Everything crosses the network (no node shares memory between its ranks), and every core
//! computes at the rate one core reaches here alone: both make the model optimistic about
//! compute and pessimistic about communication on a real node.

use crate::store::table::Row;
use schema::record::columns;
use schema::transform::transform_length;
use std::f64::consts::PI;

/// The four ways the solver runs a 2D case that the model follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SolverPath {
    /// Forward Euler, stencil backend.
    EulerStencil,
    /// Forward Euler, FFT backend.
    EulerFft,
    /// Crank–Nicolson, CG with the sine-transform preconditioner on slabs.
    CrankNicolson,
    /// Steady CG, per iteration.
    SteadyCg,
}

impl SolverPath {
    pub const ALL: [SolverPath; 4] = [
        SolverPath::EulerStencil,
        SolverPath::EulerFft,
        SolverPath::CrankNicolson,
        SolverPath::SteadyCg,
    ];

    pub fn label(self) -> &'static str {
        match self {
            SolverPath::EulerStencil => "Euler, stencil",
            SolverPath::EulerFft => "Euler, FFT",
            SolverPath::CrankNicolson => "Crank–Nicolson",
            SolverPath::SteadyCg => "steady CG (per iteration)",
        }
    }

    /// The path a summary row ran, from its case and resolved backend.
    pub fn of_row(row: &Row) -> Option<SolverPath> {
        if row.text("case.method") == Some("steady_cg") {
            return Some(SolverPath::SteadyCg);
        }
        if row.text("case.method").is_some_and(|m| m != "nonlocal")
            || row.number("case.dim") != Some(2.0)
        {
            return None;
        }
        match (row.text("case.integrator"), row.text(columns::BACKEND)) {
            (Some("crank_nicolson"), _) => Some(SolverPath::CrankNicolson),
            (Some("forward_euler") | None, Some("fft")) => Some(SolverPath::EulerFft),
            (Some("forward_euler") | None, _) => Some(SolverPath::EulerStencil),
            _ => None,
        }
    }

    /// Whether the block partition gives this path slabs of rows (the implicit integrators).
    fn slabs(self) -> bool {
        self == SolverPath::CrankNicolson
    }
}

/// A network as the model sees it: a message costs `latency_s` plus its bytes over
/// `bandwidth` (bytes per second).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Network {
    pub name: &'static str,
    pub latency_s: f64,
    pub bandwidth: f64,
}

/// InfiniBand HDR (200 Gb/s): 1.6 µs and 23.5 GB/s, as OSU's benchmarks measured it on HDR
/// (docs/scaling.md gives the sources).
pub const HDR: Network = Network {
    name: "InfiniBand HDR",
    latency_s: 1.6e-6,
    bandwidth: 23.5e9,
};

/// 10 Gigabit Ethernet, MPI over TCP: 20 µs, and 1.1 GB/s, just under the line rate.
pub const TEN_GBE: Network = Network {
    name: "10 GbE",
    latency_s: 20.0e-6,
    bandwidth: 1.1e9,
};

/// What one step of a path costs and sends, from the runs of a study.
#[derive(Clone, Debug, PartialEq)]
pub struct Rates {
    pub path: SolverPath,
    /// Horizon in cells.
    pub m: f64,
    /// Seconds per node per step on one core (the FFT: per W log₂ W of its window).
    pub compute: f64,
    /// Crank–Nicolson: the sine transform's part of `compute`, per node and log₂ n, per CG
    /// iteration; its iterations per step. Zero for the other paths.
    pub transform: f64,
    pub iterations: f64,
    /// Per step: halo exchanges, reductions, all-to-alls (counted by the runs over ranks).
    pub halos: f64,
    pub reductions: f64,
    pub all_to_alls: f64,
}

/// One prediction's parts, in seconds per step, and the bytes it moves.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Prediction {
    pub compute_s: f64,
    pub halo_s: f64,
    pub reduction_s: f64,
    pub all_to_all_s: f64,
    /// Ghost values of one halo exchange, all ranks together.
    pub ghosts: f64,
    /// Bytes one all-to-all sends between ranks, all ranks together.
    pub all_to_all_bytes: f64,
}

impl Prediction {
    pub fn total_s(&self) -> f64 {
        self.compute_s + self.halo_s + self.reduction_s + self.all_to_all_s
    }
}

/// p_x × p_y blocks for P ranks as the block partition chooses them: slabs (1 × P) for the
/// implicit integrators, else the most nearly square factorisation.
pub fn blocks(path: SolverPath, ranks: usize) -> (usize, usize) {
    if path.slabs() {
        return (1, ranks);
    }
    let px = (1..=ranks)
        .filter(|px| ranks.is_multiple_of(*px) && px * px <= ranks)
        .max()
        .unwrap_or(1);
    (px, ranks / px)
}

/// Ghost nodes of one halo exchange, all ranks together, for p_x × p_y blocks of an n × n grid
/// and a horizon of m cells.
pub fn ghosts(n: f64, m: f64, (px, py): (usize, usize)) -> f64 {
    let (cx, cy) = ((px - 1) as f64, (py - 1) as f64);
    2.0 * m * n * (cx + cy) + PI * m * m * cx * cy
}

/// Values an all-to-all transpose of an n × n grid in P slabs sends between ranks: all but each
/// rank's own block of h_q², n² − Σ h_q² with h_q = ⌊(q+1)n/P⌋ − ⌊qn/P⌋.
pub fn transposed_values(n: usize, ranks: usize) -> f64 {
    let rows = (0..ranks).map(|q| ((q + 1) * n / ranks - q * n / ranks) as f64);
    (n * n) as f64 - rows.map(|h| h * h).sum::<f64>()
}

/// The predicted step of `rates`' path on `ranks` ranks of an n × n grid over `network`.
pub fn predict(rates: &Rates, n: usize, ranks: usize, network: &Network) -> Prediction {
    let (nodes, p) = ((n * n) as f64, ranks as f64);
    let shape = blocks(rates.path, ranks);
    let per_rank = nodes / p;
    let compute_s = match rates.path {
        SolverPath::EulerFft => {
            let points = fft_points(n, rates.m as usize, shape);
            rates.compute * points * points.log2()
        }
        SolverPath::CrankNicolson => {
            (rates.iterations + 1.0)
                * per_rank
                * (rates.compute + rates.transform * (n as f64).log2())
        }
        SolverPath::EulerStencil | SolverPath::SteadyCg => rates.compute * per_rank,
    };
    if ranks == 1 {
        return Prediction {
            compute_s,
            ..Prediction::default()
        };
    }
    let (alpha, beta) = (network.latency_s, network.bandwidth);
    let ghosts = ghosts(n as f64, rates.m, shape);
    let messages = match shape {
        (1, 2) | (2, 1) => 1.0,
        (1, _) | (_, 1) => 2.0,
        _ => 8.0,
    };
    let all_to_all_bytes = 8.0 * transposed_values(n, ranks);
    Prediction {
        compute_s,
        halo_s: rates.halos * (messages * alpha + 8.0 * ghosts / p / beta),
        reduction_s: rates.reductions * 2.0 * p.log2().ceil() * alpha,
        all_to_all_s: rates.all_to_alls * ((p - 1.0) * alpha + all_to_all_bytes / p / beta),
        ghosts,
        all_to_all_bytes,
    }
}

/// Points of the FFT backend's transform on a rank of p_x × p_y blocks: along each axis its window
/// (its block and the ghosts beyond each side that has a neighbour: two for an inner block of
/// three or more, one for two, none for one), padded by the reach against wrap-around and rounded
/// up to a fast length, as `FftOperator::on_window` does.
pub fn fft_points(n: usize, m: usize, (px, py): (usize, usize)) -> f64 {
    let axis = |parts: usize| {
        let sides = parts.min(3) - 1;
        transform_length(n / parts + sides * m + m) as f64
    };
    axis(px) * axis(py)
}

/// The rates of each path from a study's summary rows: compute from its one-rank, one-thread
/// runs at the largest n, the counts per step from its runs over the fewest ranks above one.
/// A path without both is left out.
pub fn fit(rows: &[&Row]) -> Vec<Rates> {
    SolverPath::ALL
        .iter()
        .filter_map(|&path| {
            let alone = alone(rows, path)?;
            let spread = rows
                .iter()
                .filter(|r| SolverPath::of_row(r) == Some(path) && ranks(r) > 1.0)
                .filter(|r| r.get(columns::HALO_EXCHANGES).is_some())
                .min_by(|a, b| ranks(a).total_cmp(&ranks(b)))?;
            let n = alone.number("case.n")?;
            let m = alone.number(columns::M).or(alone.number("case.m"))?;
            let step = alone.number("step_s_median")?;
            // Counts per step, or per iteration for steady CG.
            let per = match path {
                SolverPath::SteadyCg => spread.number(columns::ITERATIONS)?,
                _ => spread.number(columns::STEPS_DONE)?,
            };
            let count = |name: &str| spread.number(&format!("traffic.{name}")).map(|c| c / per);
            let iterations = alone.number(columns::SOLVE_ITERATIONS_MEAN).unwrap_or(0.0);
            let (compute, transform) = match path {
                SolverPath::EulerFft => {
                    let points = fft_points(n as usize, m as usize, (1, 1));
                    (step / (points * points.log2()), 0.0)
                }
                SolverPath::CrankNicolson => {
                    // The operator's share from the Euler path's rate when the study ran it,
                    // the rest the transform's.
                    let stencil = fit_stencil_rate(rows).unwrap_or(0.0);
                    let per_apply = step / (iterations + 1.0) / (n * n);
                    (stencil, ((per_apply - stencil) / n.log2()).max(0.0))
                }
                _ => (step / (n * n), 0.0),
            };
            Some(Rates {
                path,
                m,
                compute,
                transform,
                iterations,
                halos: count("halo_exchanges")?,
                reductions: count("reductions")?,
                all_to_alls: count("all_to_alls").unwrap_or(0.0),
            })
        })
        .collect()
}

/// A row's rank count (1 if none).
fn ranks(row: &Row) -> f64 {
    row.number(columns::RANKS).unwrap_or(1.0)
}

/// The run of `path` the compute rate comes from: on one rank and one thread, the largest n.
fn alone<'a>(rows: &[&'a Row], path: SolverPath) -> Option<&'a Row> {
    let grid = |row: &Row| row.number("case.n").unwrap_or(0.0);
    rows.iter()
        .copied()
        .filter(|r| SolverPath::of_row(r) == Some(path) && ranks(r) == 1.0)
        .filter(|r| r.number("case.threads").unwrap_or(1.0) == 1.0)
        .max_by(|a, b| grid(a).total_cmp(&grid(b)))
}

/// The stencil's seconds per node per step, from the study's one-rank Euler run.
fn fit_stencil_rate(rows: &[&Row]) -> Option<f64> {
    let alone = alone(rows, SolverPath::EulerStencil)?;
    let n = alone.number("case.n")?;
    Some(alone.number("step_s_median")? / (n * n))
}

/// The rank count where the predicted parallel efficiency T(1)/(P T(P)) (strong) first falls
/// below one half among `ranks`, if it does.
pub fn half_efficiency(
    rates: &Rates,
    n: usize,
    ranks: &[usize],
    network: &Network,
) -> Option<usize> {
    let one = predict(rates, n, 1, network).total_s();
    ranks
        .iter()
        .copied()
        .find(|&p| one / (p as f64 * predict(rates, n, p, network).total_s()) < 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rates(path: SolverPath) -> Rates {
        Rates {
            path,
            m: 4.0,
            compute: 1e-9,
            transform: 1e-10,
            iterations: 3.0,
            halos: 1.0,
            reductions: 1.0,
            // Two transposes per preconditioner application, one per iteration and one more.
            all_to_alls: if path == SolverPath::CrankNicolson {
                8.0
            } else {
                0.0
            },
        }
    }

    /// The counts the block partition and the transposes make, against their literal sums.
    #[test]
    fn ghosts_and_transposed_values_count_what_the_partition_makes() {
        // The FFT's transform: 1024 + 32 is 1056 = 2⁵·3·11, not 7-smooth; 1080 = 2³·3³·5 is.
        assert_eq!(transform_length(1056), 1080);
        assert_eq!(fft_points(1024, 32, (1, 1)), 1080.0 * 1080.0);
        // Two slabs: one side of ghosts along y.
        assert_eq!(
            fft_points(1024, 32, (1, 2)),
            1080.0 * transform_length(512 + 64) as f64
        );
        assert_eq!(blocks(SolverPath::EulerStencil, 16), (4, 4));
        assert_eq!(blocks(SolverPath::EulerStencil, 8), (2, 4));
        assert_eq!(blocks(SolverPath::CrankNicolson, 8), (1, 8));
        // Two slabs: each side of the one cut sends m rows of n.
        assert_eq!(ghosts(100.0, 4.0, (1, 2)), 800.0);
        // n = 40 over 3 slabs of 13, 13, 14 rows: 1600 − 169 − 169 − 196.
        assert_eq!(transposed_values(40, 3), 1066.0);
        assert_eq!(transposed_values(40, 1), 0.0);
    }

    /// On one rank nothing is sent; strong scaling divides the compute and adds communication,
    /// so a slower network is never faster, and the efficiency falls below one half somewhere
    /// between 1 and 4096 ranks on 10 GbE for a small grid.
    #[test]
    fn a_prediction_divides_the_work_and_pays_for_the_network() {
        for path in SolverPath::ALL {
            let r = rates(path);
            let one = predict(&r, 1024, 1, &HDR);
            assert_eq!(one.total_s(), one.compute_s, "{path:?}");
            let (fast, slow) = (predict(&r, 1024, 64, &HDR), predict(&r, 1024, 64, &TEN_GBE));
            assert!(fast.compute_s < one.compute_s / 32.0, "{path:?}");
            assert!(fast.total_s() < slow.total_s(), "{path:?}");
            let ranks: Vec<usize> = (0..=12).map(|k| 1 << k).collect();
            assert!(
                half_efficiency(&r, 1024, &ranks, &TEN_GBE).is_some(),
                "{path:?}"
            );
        }
        let cn = predict(&rates(SolverPath::CrankNicolson), 1024, 4, &HDR);
        assert_eq!(cn.all_to_all_bytes, 8.0 * transposed_values(1024, 4));
        assert!(cn.all_to_all_s > 0.0);
        assert_eq!(
            predict(&rates(SolverPath::EulerStencil), 1024, 4, &HDR).all_to_all_s,
            0.0
        );
    }
}
