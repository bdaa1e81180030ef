//! Fields for ParaView: VTK XML image data (`.vti`), one file per output time, and a `.pvd`
//! collection that lists them with their times.
//!
//! Hand-written rather than through `vtkio`, the one Rust VTK crate: its last release is a 2023
//! release candidate pinned to an old quick-xml, and image data needs only a header and one array.
//! The values are appended raw (little-endian f64 behind a UInt64 byte count), so they are
//! exact, and a 1024² frame is 8 MB rather than about 20 MB of decimal text.

use crate::discretization::grid::Lattice;
use std::fmt::Write;

/// The `.vti` file of `values` on `lattice`, as the point array `name`.
pub fn image_data(lattice: &Lattice, name: &str, values: &[f64]) -> Vec<u8> {
    assert_eq!(values.len(), lattice.nodes(), "one value per node");
    let last = lattice.n - 1;
    let (last_y, origin_y) = match lattice.dim {
        1 => (0, 0.0),
        _ => (last, lattice.origin),
    };
    let extent = format!("0 {last} 0 {last_y} 0 0");
    let h = lattice.spacing;
    let mut header = String::new();
    let _ = write!(
        header,
        r#"<?xml version="1.0"?>
<VTKFile type="ImageData" version="1.0" byte_order="LittleEndian" header_type="UInt64">
  <ImageData WholeExtent="{extent}" Origin="{} {origin_y} 0" Spacing="{h} {h} {h}">
    <Piece Extent="{extent}">
      <PointData Scalars="{name}">
        <DataArray type="Float64" Name="{name}" NumberOfComponents="1" format="appended" offset="0"/>
      </PointData>
    </Piece>
  </ImageData>
  <AppendedData encoding="raw">
   _"#,
        lattice.origin
    );
    let mut bytes = header.into_bytes();
    bytes.extend_from_slice(&(8 * values.len() as u64).to_le_bytes());
    for v in values {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes.extend_from_slice(b"\n  </AppendedData>\n</VTKFile>\n");
    bytes
}

/// The `.pvd` collection of `(time, file)` entries, files relative to the collection.
pub fn collection(entries: &[(f64, String)]) -> String {
    let mut text = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n",
    );
    for (time, file) in entries {
        let _ = writeln!(
            text,
            r#"    <DataSet timestep="{time}" group="" part="0" file="{file}"/>"#
        );
    }
    text.push_str("  </Collection>\n</VTKFile>\n");
    text
}

/// File names for `count` frames: `u_000.vti`, … wide enough to sort in time order.
pub fn frame_names(count: usize) -> Vec<String> {
    let width = count.saturating_sub(1).to_string().len();
    (0..count).map(|k| format!("u_{k:0width$}.vti")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_data_holds_its_values_raw_after_the_byte_count() {
        let lattice = Lattice {
            dim: 2,
            n: 3,
            origin: 0.5,
            spacing: 1.0,
        };
        let values: Vec<f64> = (0..9).map(|i| i as f64 / 7.0).collect();
        let bytes = image_data(&lattice, "u", &values);
        let marker = b"<AppendedData encoding=\"raw\">\n   _";
        let start = bytes
            .windows(marker.len())
            .position(|w| w == marker)
            .unwrap()
            + marker.len();
        let count = u64::from_le_bytes(bytes[start..start + 8].try_into().unwrap());
        assert_eq!(count, 72);
        let stored: Vec<f64> = bytes[start + 8..start + 80]
            .chunks(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(stored, values);
        let header = String::from_utf8_lossy(&bytes[..start]);
        assert!(header.contains(r#"WholeExtent="0 2 0 2 0 0" Origin="0.5 0.5 0""#));
    }

    #[test]
    fn frame_names_sort_in_time_order() {
        assert_eq!(frame_names(1), ["u_0.vti"]);
        let names = frame_names(11);
        assert_eq!(
            (names[0].as_str(), names[10].as_str()),
            ("u_00.vti", "u_10.vti")
        );
    }
}
