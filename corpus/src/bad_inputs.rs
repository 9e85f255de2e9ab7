//! Malformed variants of each input kind (`--bad-inputs DIR`), with what a good tool must say.
//!
//! One file (or small campaign folder) per malformation listed in the ingest issue. Each is
//! derived from a well-formed sample of the same writer, changed in exactly one way, so a
//! reader that fails on it fails for the documented reason. The README lists, per file, the
//! location and expectation an error message must name.

use std::path::Path;

use crate::instruments::{navcam, opencv, ply, vicon};
use crate::sink::Sink;
use crate::CorpusError;

/// The bad inputs: (relative path, bytes, what a good tool must report).
fn cases() -> Result<Vec<(String, Vec<u8>, String)>, CorpusError> {
    let mut v: Vec<(String, Vec<u8>, String)> = Vec::new();
    let mut add = |p: &str, b: Vec<u8>, why: &str| v.push((p.to_string(), b, why.to_string()));

    let good_ply = ply::points(
        &[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]],
        &[-5.0, -6.0, -7.0],
        "bad-inputs",
    );
    add("truncated.ply", good_ply[..good_ply.len() - 20].to_vec(),
        "header declares 3 vertices (48 body bytes) but the body has 28: error names the file, the element `vertex`, and the byte offset where data ended");
    add(
        "nan_coordinates.asc",
        b"X[m] Y[m] Z[m] Reflectance[dB]\n1.0000 2.0000 0.5000 -5.20\n1.1000 nan 0.5100 -5.10\n"
            .to_vec(),
        "line 3, column 2 (Y[m]): expected a finite number, found `nan`",
    );
    add(
        "mixed_delimiters.asc",
        b"X[m] Y[m] Z[m] Reflectance[dB]\n1.0000 2.0000 0.5000 -5.20\n1.1000;2.1000;0.5100;-5.10\n"
            .to_vec(),
        "line 3: expected 4 space-separated fields like line 2, found `;`-separated fields",
    );
    add("vrml_index_out_of_range.wrl",
        b"#VRML V2.0 utf8\nShape { geometry IndexedFaceSet {\n  coord Coordinate { point [ 0 0 0, 1 0 0, 0 1 0 ] }\n  coordIndex [ 0 1 2 -1, 0 2 7 -1 ]\n} }\n".to_vec(),
        "coordIndex entry 7 (face 2, line 4) is out of range: only 3 points (0..2)");
    let tracks = vicon::tracks(
        &[[1.0, 2.0, 0.1], [2.0, 1.0, 0.2]],
        5,
        false,
        &mut crate::seeding::stage_rng(0, "bad"),
    );
    let good_csv = vicon::nexus_csv("Testbed", &["Marker1", "Marker2"], &tracks, 1);
    let no_units: Vec<&str> = good_csv
        .lines()
        .filter(|l| !l.starts_with(",,mm"))
        .collect();
    add("vicon_no_units.csv", (no_units.join("\n") + "\n").into_bytes(),
        "line 7: expected the units row (`,,mm,mm,mm,...`) after `Frame,Sub Frame,X,Y,Z,...`, found a data row");
    let mut text_cell: Vec<String> = good_csv.lines().map(str::to_string).collect();
    if let Some(l) = text_cell.get_mut(9) {
        *l = l.replacen(",", ",oops", 3).replacen(",oops", ",", 2);
    }
    add("vicon_text_in_numeric.csv", (text_cell.join("\n") + "\n").into_bytes(),
        "line 10: a coordinate cell holds text (`oops...`): expected a number or an empty cell (gap)");
    let mut yaml = String::from("%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n");
    opencv::matrix(
        &mut yaml,
        "camera_matrix",
        3,
        2,
        &[500.0, 0.0, 0.0, 500.0, 0.0, 0.0],
    );
    opencv::matrix(
        &mut yaml,
        "distortion_coefficients",
        1,
        5,
        &[-0.2, 0.05, 0.0, 0.0, 0.0],
    );
    add(
        "camera_matrix_3x2.yaml",
        yaml.into_bytes(),
        "camera_matrix is 3x2: expected a 3x3 matrix (name the key `camera_matrix` and its line)",
    );
    let png = navcam::png_grey(&[128u8; 64 * 48], 64, 48)
        .map_err(CorpusError::encode("PNG", Path::new("truncated.png")))?;
    add("truncated.png", png[..png.len() / 2].to_vec(), "the PNG ends inside its image data: error names the file and says it is truncated/corrupt, not a panic");
    add(
        "empty.csv",
        Vec::new(),
        "the file is empty: expected a Vicon/tie-point header on line 1",
    );
    add(
        "empty.asc",
        Vec::new(),
        "the file is empty: expected a RiSCAN ASCII header or data line on line 1",
    );
    let markers = good_csv.into_bytes();
    let campaign = |file: &str| {
        format!(
        "schema = \"regolith.campaign/1\"\nname = \"bad\"\n\n[ground]\nmarkers = \"vicon/markers.csv\"\nmarker_radius_m = 0.013\n\n\
         [[scan]]\nname = \"pos1\"\nfile = \"{file}\"\ncolumns = \"x y z reflectance\"\ntiepoints = \"scans/pos1_tiepoints.csv\"\n"
    )
    };
    let tie = b"Name,X,Y,Z\nMarker1,1.0,2.0,0.1\n".to_vec();
    for (dir, file, why) in [
        ("missing_file", "scans/absent.asc", "campaign.toml [[scan]] pos1 `file`: scans/absent.asc does not exist (name the key and the path)"),
        ("path_escape", "../../outside.asc", "campaign.toml [[scan]] pos1 `file`: ../../outside.asc escapes the campaign folder"),
    ] {
        add(&format!("{dir}/campaign.toml"), campaign(file).into_bytes(), why);
        add(&format!("{dir}/vicon/markers.csv"), markers.clone(), "(valid; part of the campaign)");
        add(&format!("{dir}/scans/pos1_tiepoints.csv"), tie.clone(), "(valid; part of the campaign)");
    }
    Ok(v)
}

/// Writes the bad inputs and their README into `dir`; returns the files written.
pub fn write_bad_inputs(dir: &Path) -> Result<Vec<String>, CorpusError> {
    let mut sink = Sink::new(dir)?;
    let mut readme = String::from(
        "# Malformed inputs (regolith-corpus --bad-inputs)\n\nEach file is a well-formed sample broken in one way. \
         A good tool rejects it without panicking, with a message naming the file, the location and what it expected:\n\n\
         | file | a good tool must say |\n|---|---|\n",
    );
    for (rel, bytes, why) in cases()? {
        sink.write(&rel, &bytes)?;
        if !why.starts_with("(valid") {
            readme.push_str(&format!("| `{rel}` | {why} |\n"));
        }
    }
    sink.write("README.md", readme.as_bytes())?;
    Ok(sink.files())
}
