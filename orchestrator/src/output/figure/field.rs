//! Field: a heat map (2D) or profile (1D) of one point's final field and its error.

use super::series::*;
use crate::output::draw::{Axis, HeatMap, Panel};
use crate::store::table::Row;

/// The final field of the one point `rows` holds (column `x`) and its error (column `y`): heat
/// maps in 2D, profiles in 1D.
pub(super) fn field(rows: &[&Row], x: &str, y: &str) -> Result<Vec<Panel>, String> {
    let [row] = rows else {
        return Err(format!(
            "selects {} points, but a field figure shows one; narrow the conditions (e.g. `n == 128 && method == 'nonlocal'`)",
            rows.len()
        ));
    };
    let stem = x.strip_suffix(".values").unwrap_or("field");
    let size = |name: &str| row.number(&format!("{stem}.{name}"));
    let (Some(nx), Some(ny), Some(lower), Some(upper)) =
        (size("nx"), size("ny"), size("lower"), size("upper"))
    else {
        return Err(format!("selects a point without a `{stem}` snapshot; set `field_snapshot` (e.g. 64) in the study's base"));
    };
    let (nx, ny) = (nx as usize, ny as usize);
    let values = numbers(row.get(x));
    let error = numbers(row.get(y));
    let mut panels = vec![field_panel(
        "u at the final time",
        nx,
        ny,
        (lower, upper),
        values,
        false,
    )];
    if !error.is_empty() {
        panels.push(field_panel(
            "error u − u_exact",
            nx,
            ny,
            (lower, upper),
            error,
            true,
        ));
    }
    Ok(panels)
}

/// One field panel: cells coloured by value in 2D, the profile over x in 1D.
fn field_panel(
    title: &str,
    nx: usize,
    ny: usize,
    (lower, upper): (f64, f64),
    values: Vec<f64>,
    signed: bool,
) -> Panel {
    let (heat, series) = match ny > 1 {
        true => {
            let heat = HeatMap {
                nx,
                ny,
                lower,
                upper,
                values,
                diverging: signed,
            };
            (Some(heat), Vec::new())
        }
        false => {
            let dx = (upper - lower) / nx as f64;
            let profile = values
                .iter()
                .enumerate()
                .map(|(i, &v)| (lower + (i as f64 + 0.5) * dx, v))
                .collect();
            (None, vec![series(title.to_string(), profile)])
        }
    };
    let y_label = if heat.is_some() { "y" } else { title };
    Panel {
        title: title.to_string(),
        x: Axis::linear("x"),
        y: Axis::linear(y_label),
        series,
        guides: Vec::new(),
        heat,
    }
}
