//! A figure as a study file names it: which kind, which columns, which rows. Drawing it is the
//! output layer's work (`output::figure`); the study model only reads and checks the spec.

use schema::record::columns;
use serde::{Deserialize, Serialize};

/// One figure of a study file, e.g.
/// `{"name": "convergence", "kind": "convergence", "series": ["method"], "where": ["dim == 2"]}`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FigureSpec {
    /// The file: `results/<study>/figures/<name>.svg`.
    pub name: String,
    pub kind: FigureKind,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub title: Option<String>,
    /// Columns of the summary table (a case field may be named without `case.`); each kind has
    /// defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x: Option<String>,
    /// A column, or `abs(column)` for its magnitude (signed values on a log axis).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub y: Option<String>,
    /// Columns whose values tell the series apart.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub series: Option<Vec<String>>,
    /// Conditions on a row, as in a study's `where`.
    #[serde(default, rename = "where", skip_serializing_if = "Vec::is_empty")]
    pub filter: Vec<String>,
}

#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub enum FigureKind {
    /// Time, speedup and efficiency against workers, with ideal lines and min–max bands.
    StrongScaling,
    /// Efficiency T(p₀)/T(p) against workers, the problem growing with them.
    WeakScaling,
    /// Error against h on log–log axes, the fitted slope written on each series.
    Convergence,
    /// Run time against error, one series per method, the Pareto front marked.
    WorkPrecision,
    /// max|u| at the end against dt/dt_stable, diverged runs as crosses, the bound at 1.
    Stability,
    /// c_tot(t) of each point.
    TimeSeries,
    /// Bond updates per second against the horizon m, one panel per grid size n, one series per
    /// backend that ran, and the measured crossover where the FFT overtakes the stencil marked.
    Throughput,
    /// Heat maps (profiles in 1D) of one point's final field and of its error, from the
    /// snapshot the case's `field_snapshot` puts into the record.
    Field,
    /// Steady solvers (\[XGDF]): iterations and solve time against the subdomains, one series
    /// per method and preconditioner. CG has no subdomains: its points sit at the subdomain count
    /// of the FETI points that solve the same L.
    SolverComparison,
    /// The scaling model fitted to the study's runs (one rank and over ranks, each path):
    /// predicted strong scaling of 16384² to 4096 ranks and weak scaling at 1024² per rank on
    /// InfiniBand HDR and 10 GbE, and the model against the runs (docs/scaling.md).
    ScalingModel,
    /// Boundary searches (a study's `boundary` question): the measured boundaries along a swept
    /// field (`m` by default) with the theory's dashed, and measured / predicted zoomed to the
    /// search's tolerance. Drawn from `<study>-boundaries.parquet`, not the summary.
    Boundaries,
}

impl FigureKind {
    /// Default x, y and series columns.
    pub fn defaults(self) -> (&'static str, &'static str, &'static str) {
        match self {
            FigureKind::StrongScaling | FigureKind::WeakScaling => {
                ("workers", "solve_s_median", "scaling_series")
            }
            FigureKind::Convergence => (columns::H, columns::ERROR_L2_NORM, "refinement_series"),
            FigureKind::WorkPrecision => (columns::ERROR_L2_NORM, "solve_s_median", "case.method"),
            FigureKind::Stability => ("case.cfl", columns::MAX_ABS, "case.method"),
            FigureKind::TimeSeries => (columns::C_TOT_TIME, columns::C_TOT, "point"),
            FigureKind::Throughput => ("case.m", "bond_updates_per_s", columns::BACKEND),
            FigureKind::Field => (columns::FIELD_VALUES, columns::FIELD_ERROR, "point"),
            FigureKind::SolverComparison => {
                (columns::SUBDOMAINS, columns::ITERATIONS, "case.method")
            }
            FigureKind::ScalingModel => (columns::RANKS, "step_s_median", "case.method"),
            FigureKind::Boundaries => ("m", "boundary", ""),
        }
    }
}
