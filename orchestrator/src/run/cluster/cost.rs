//! The cost model: a case's work in nodes × bonds × steps, the relative measure that orders
//! and packs points no run has timed yet (`balance`), and that the study's timed points turn
//! into seconds (`limits`).

use crate::run::plan::Planned;
use schema::case::Case;
use schema::choices::Method;

/// The work of a planned point's case; none for a case this build cannot read.
pub fn work_of(point: &Planned) -> Option<f64> {
    Some(work(&point.case.as_ref().ok()?.case()?))
}

/// The cost model's work of a case: its nodes, the bonds (stencil points) of each, and its
/// steps (those to `t_end`, from `dt` or, at a CFL number, from a step ∝ h², plus the steps of
/// its amplification measurement). A relative measure, not a time.
pub fn work(case: &Case) -> f64 {
    let (n, dim) = (case.n as f64, case.dim as i32);
    let nodes = n.powi(dim);
    let reach = case
        .m
        .map(|m| m as f64)
        .or(case.eps.map(|eps| (eps * n).ceil()))
        .unwrap_or(1.0);
    let bonds = match case.method {
        Method::FdExplicit | Method::Adi | Method::Pse => 2.0 * dim as f64 + 1.0,
        _ => (2.0 * reach + 1.0).powi(dim),
    };
    let steps = match (case.t_end, case.dt, case.cfl) {
        (Some(t), Some(dt), _) if dt > 0.0 => (t / dt).ceil(),
        (Some(t), None, Some(cfl)) if cfl > 0.0 => (t * n * n * 2.0 * dim as f64 / cfl).ceil(),
        _ => 1.0,
    };
    let measuring = case.amplification_steps.unwrap_or(0) as f64;
    nodes * bonds * (steps.max(1.0) + measuring)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cost_model_counts_nodes_bonds_and_steps() {
        let case = |json: serde_json::Value| serde_json::from_value::<Case>(json).unwrap();
        let base = serde_json::json!({"dim": 2, "n": 10, "m": 3, "t_end": 0.1, "dt": 0.01});
        // 100 nodes × 7² bonds × 10 steps.
        assert_eq!(work(&case(base.clone())), 100.0 * 49.0 * 10.0);
        let mut measured = base.clone();
        measured["amplification_steps"] = 400.into();
        assert_eq!(work(&case(measured)), 100.0 * 49.0 * 410.0);
        let mut local = base;
        local["method"] = "fd_explicit".into();
        local.as_object_mut().unwrap().remove("m");
        assert_eq!(work(&case(local)), 100.0 * 5.0 * 10.0);
    }
}
