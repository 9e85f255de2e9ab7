//! Errors a user can act on: the mistakes a new user makes on the first day, one row each —
//! a setup that breaks one thing, the command, and what the message must say. Every row must
//! exit 2 (usage or input error; never 3, a panic), name the file (and the line where there is
//! one) and say what to do; a row that touches a database must leave its folder byte for byte
//! as it was (the tree is hashed before and after).
//!
//! The campaigns are copies of the checked-in demo campaign (`corpus/demo`) with one thing
//! broken; the database is the small sample release of `regolith_tests::sample`, built once and
//! shared by every row.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::collections::BTreeMap;
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use std::process::Command;

use common::copy_dir;
use regolith_reader::Writer;

/// One row of the table.
struct Row {
    /// What the user got wrong.
    mistake: String,
    /// The command line after `regolith`.
    args: Vec<String>,
    /// Substrings stderr must contain: the file, the place, what was expected, the fix.
    words: Vec<String>,
    /// Folders that must be byte for byte unchanged by the command (the database).
    unchanged: Vec<PathBuf>,
    /// Paths the failed command must not have created.
    absent: Vec<PathBuf>,
}

fn row(mistake: &str, args: &[&str], words: &[&str]) -> Row {
    Row {
        mistake: mistake.to_string(),
        args: args.iter().map(|s| s.to_string()).collect(),
        words: words.iter().map(|s| s.to_string()).collect(),
        unchanged: Vec::new(),
        absent: Vec::new(),
    }
}

impl Row {
    fn unchanged(mut self, dir: &Path) -> Row {
        self.unchanged.push(dir.to_path_buf());
        self
    }
    fn absent(mut self, path: &Path) -> Row {
        self.absent.push(path.to_path_buf());
        self
    }
    fn word(mut self, w: String) -> Row {
        self.words.push(w);
        self
    }
}

/// Every file and folder under `dir` with a hash of its bytes (`None` for a folder).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Option<(u64, u64)>> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<PathBuf, Option<(u64, u64)>>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            let rel = p.strip_prefix(root).unwrap().to_path_buf();
            if p.is_dir() {
                out.insert(rel, None);
                walk(root, &p, out);
            } else {
                let bytes = std::fs::read(&p).unwrap();
                let mut h = std::collections::hash_map::DefaultHasher::new();
                bytes.hash(&mut h);
                out.insert(rel, Some((bytes.len() as u64, h.finish())));
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// A copy of the demo campaign in `tmp/<name>`.
fn demo(tmp: &Path, name: &str) -> PathBuf {
    let dir = tmp.join(name);
    copy_dir(&regolith_tests::workspace_root().join("corpus/demo"), &dir);
    dir
}

/// Replaces the first `from` in a text file by `to` (which must be there).
fn edit(path: &Path, from: &str, to: &str) {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(text.contains(from), "{}: no {from:?}", path.display());
    std::fs::write(path, text.replacen(from, to, 1)).unwrap();
}

/// The 1-based line of the first line of `path` containing `needle`.
fn line_of(path: &Path, needle: &str) -> usize {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .position(|l| l.contains(needle))
        .unwrap()
        + 1
}

/// Writes `unit` over the `mm` of the units row of campaign `c`'s ground-marker Vicon file.
fn rewrite_vicon_units(c: &Path, unit: &str) {
    let markers = c.join("vicon/markers.csv");
    let text = std::fs::read_to_string(&markers).unwrap();
    let broken: Vec<String> = text
        .lines()
        .map(|l| {
            if l.starts_with(",,mm") {
                l.replace("mm", unit)
            } else {
                l.to_string()
            }
        })
        .collect();
    std::fs::write(&markers, broken.join("\n") + "\n").unwrap();
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn first_day_mistakes_name_the_file_and_the_fix() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let db = t.join("terrain.db");
    regolith_tests::sample::build(&Writer::create_or_open(&db).unwrap(), "1.0.0").unwrap();
    let dbs = s(&db).to_string();
    let dbs = dbs.as_str();
    let mut rows: Vec<Row> = Vec::new();

    // 1. A campaign path that does not exist.
    let nowhere = t.join("no-such-dir");
    let new_db = t.join("new.db");
    rows.push(
        row(
            "campaign path that does not exist",
            &["compile", s(&nowhere), "--db", s(&new_db)],
            &[
                "no-such-dir",
                "no such file or folder",
                "give the campaign folder",
                "campaign.toml",
            ],
        )
        .absent(&new_db),
    );
    // 1b. A folder that is not a campaign: the database itself, or an empty folder.
    rows.push(
        row(
            "a database given as the campaign",
            &["compile", dbs, "--check"],
            &[
                "terrain.db",
                "is a regolith database, not a campaign",
                "campaign.toml",
            ],
        )
        .unchanged(&db),
    );
    let holder = t.join("holder");
    std::fs::create_dir_all(&holder).unwrap();
    let nested = demo(&holder, "my-campaign");
    rows.push(row(
        "the folder above the campaign",
        &["compile", s(&holder), "--check"],
        &["holds no campaign.toml", "did you mean", s(&nested)],
    ));

    // 2. campaign.toml without its schema line.
    let c = demo(t, "no-schema");
    edit(
        &c.join("campaign.toml"),
        "schema = \"regolith.campaign/1\"\n",
        "",
    );
    rows.push(
        row(
            "campaign.toml without `schema`",
            &["compile", s(&c), "--db", dbs],
            &[
                "campaign.toml",
                "missing field `schema`",
                "`schema = \"regolith.campaign/1\"`",
                "add that line at the top",
            ],
        )
        .unchanged(&db),
    );
    // 2b. A misspelt key (already good: keep it so).
    let c = demo(t, "typo");
    edit(&c.join("campaign.toml"), "marker_radius_m", "marker_radius");
    let line = line_of(&c.join("campaign.toml"), "marker_radius");
    rows.push(
        row(
            "misspelt key",
            &["compile", s(&c), "--db", dbs],
            &["campaign.toml", "did you mean `marker_radius_m`"],
        )
        .word(format!("line {line}"))
        .unchanged(&db),
    );

    // 3. A scan without tie points: the file missing, empty, not named, or no key at all.
    let c = demo(t, "tiepoints-missing");
    std::fs::remove_file(c.join("scans/pos1_tiepoints.csv")).unwrap();
    let line = line_of(&c.join("campaign.toml"), "pos1_tiepoints.csv");
    rows.push(
        row(
            "tie-point file missing",
            &["compile", s(&c), "--db", dbs],
            &[
                "[[scan]] \"pos1\" tiepoints",
                "\"scans/pos1_tiepoints.csv\" does not exist",
                "campaign.toml",
                "Name,X,Y,Z",
                "sop = ",
            ],
        )
        .word(format!("line {line}"))
        .unchanged(&db),
    );
    let c = demo(t, "tiepoints-empty");
    std::fs::write(c.join("scans/pos1_tiepoints.csv"), "").unwrap();
    for args in [
        vec!["compile", s(&c), "--db", dbs],
        vec!["compile", s(&c), "--check"],
    ] {
        rows.push(
            row(
                "tie-point file empty",
                &args,
                &[
                    "[[scan]] \"pos1\" tiepoints",
                    "scans/pos1_tiepoints.csv",
                    "the file is empty",
                    "Name,X,Y,Z",
                    "sop = ",
                ],
            )
            .unchanged(&db),
        );
    }
    let c = demo(t, "tiepoints-key");
    edit(
        &c.join("campaign.toml"),
        "tiepoints = \"scans/pos1_tiepoints.csv\"\n",
        "",
    );
    let line = line_of(&c.join("campaign.toml"), "scans/pos1.asc");
    rows.push(
        row(
            "scan without a registration key",
            &["compile", s(&c), "--db", dbs],
            &[
                "[[scan]] \"pos1\" has no registration",
                "campaign.toml",
                "tiepoints = ",
                "sop = ",
            ],
        )
        .word(format!("line {line}"))
        .unchanged(&db),
    );
    let c = demo(t, "tiepoints-names");
    let tp = c.join("scans/pos1_tiepoints.csv");
    let text = std::fs::read_to_string(&tp).unwrap();
    std::fs::write(&tp, text.replace("Marker", "TP")).unwrap();
    rows.push(
        row(
            "tie points not named as the ground markers",
            &["compile", s(&c), "--db", dbs],
            &[
                "scan pos1",
                "TP1",
                "Marker1",
                "name each tie point exactly as the ground marker",
            ],
        )
        .unchanged(&db),
    );

    // 4. Wrong units in the Vicon file: `m` over millimetre values, and a unit regolith does
    //    not read.
    let c = demo(t, "vicon-metres");
    let units = line_of(&c.join("vicon/markers.csv"), ",,mm,mm,mm");
    rewrite_vicon_units(&c, "m");
    rows.push(
        row(
            "Vicon units row says m over millimetre values",
            &["compile", s(&c), "--db", dbs],
            &[
                "vicon/markers.csv",
                "says `m`",
                "millimetres",
                "change the units row to `mm`",
            ],
        )
        .word(format!("line {}", units + 1))
        .word(format!("units row (line {units})"))
        .unchanged(&db),
    );
    let c = demo(t, "vicon-inches");
    rewrite_vicon_units(&c, "in");
    rows.push(
        row(
            "Vicon units row with an unsupported unit",
            &["compile", s(&c), "--db", dbs],
            &[
                "vicon/markers.csv",
                "found \"in\"",
                "a length unit (mm, cm, m)",
                "write `mm`, `cm` or `m` in the units row",
            ],
        )
        .word(format!("line {units}"))
        .unchanged(&db),
    );
    // The same mistake compiled into a new database: the failed compile leaves no folder.
    let fresh = t.join("fresh.db");
    rows.push(
        row(
            "Vicon units row with an unsupported unit, into a new database",
            &["compile", s(&c), "--db", s(&fresh)],
            &["vicon/markers.csv", "found \"in\""],
        )
        .absent(&fresh),
    );

    // 5. A calibration for another image size than the captures'.
    let c = demo(t, "calibration-size");
    let calib = c.join("calib/navcam_left.yaml");
    edit(&calib, "image_width: 640", "image_width: 1280");
    edit(&calib, "image_height: 512", "image_height: 1024");
    rows.push(
        row(
            "calibration for another image size",
            &["compile", s(&c), "--db", dbs],
            &[
                "calib/navcam_left.yaml",
                "captures/loc01_left_a.png",
                "640x512",
                "1280x1024",
                "point [[camera]] \"navcam_left\" `calibration` at a calibration made at 640x512",
            ],
        )
        .unchanged(&db),
    );

    // 6. A capture image missing.
    let c = demo(t, "image-missing");
    std::fs::remove_file(c.join("captures/loc02_right_b.png")).unwrap();
    let line = line_of(&c.join("campaign.toml"), "loc02_right_b.png");
    rows.push(
        row(
            "capture image missing",
            &["compile", s(&c), "--db", dbs],
            &[
                "[[capture]] \"loc02\" right",
                "\"captures/loc02_right_b.png\" does not exist",
                "campaign.toml",
                "add the file, or correct the path",
            ],
        )
        .word(format!("line {line}"))
        .unchanged(&db),
    );

    // 7. An entry that does not exist.
    let entry_words = [
        "no entry \"laser/0.5\"",
        "its entries are:",
        "laser/0.05",
        "cameras/navcam_left",
        "regolith inspect",
    ];
    let to = t.join("exported");
    for args in [
        vec!["validate", dbs, "--entry", "laser/0.5"],
        vec!["gap", dbs, "--entry", "laser/0.5"],
        vec!["export", dbs, "latest", "laser/0.5", "--to", s(&to)],
        vec![
            "control",
            dbs,
            "--entry",
            "laser/0.5",
            "--texture-blur-m",
            "0.01",
        ],
        vec!["inspect", dbs, "latest", "laser/0.5"],
    ] {
        rows.push(
            row("entry that does not exist", &args, &entry_words)
                .unchanged(&db)
                .absent(&to),
        );
    }

    // 8. A release that does not exist.
    let release_words = [
        "no release matches \"demo@1.0.0\"",
        "sample@1.0.0",
        "latest",
        "name@version",
    ];
    for args in [
        vec!["inspect", dbs, "demo@1.0.0"],
        vec!["validate", dbs, "--release", "demo@1.0.0"],
        vec![
            "gap",
            dbs,
            "--release",
            "demo@1.0.0",
            "--entry",
            "laser/0.05",
        ],
        vec![
            "control",
            dbs,
            "--release",
            "demo@1.0.0",
            "--entry",
            "laser/0.05",
            "--texture-blur-m",
            "0.01",
        ],
        vec!["export", dbs, "demo@1.0.0", "laser/0.05", "--to", s(&to)],
        vec!["release", dbs, "demo@1.0.0", "--publish"],
    ] {
        rows.push(
            row("release that does not exist", &args, &release_words)
                .unchanged(&db)
                .absent(&to),
        );
    }

    // 9. A database path that is not a database.
    let empty = t.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let random = t.join("random");
    std::fs::create_dir_all(&random).unwrap();
    std::fs::write(random.join("notes.txt"), "not a database\n").unwrap();
    let parent = t.join("out");
    let inner = parent.join("db");
    copy_dir(&db, &inner);
    let db_hint = "`regolith compile CAMPAIGN --db DB` creates";
    for cmd in ["inspect", "validate", "verify", "gc"] {
        rows.push(
            row(
                "empty folder as the database",
                &[cmd, s(&empty)],
                &[
                    "empty",
                    "is not a regolith database",
                    "the folder is empty",
                    db_hint,
                ],
            )
            .unchanged(&empty),
        );
    }
    rows.push(
        row(
            "folder of other files as the database",
            &["verify", s(&random)],
            &[
                "random",
                "is not a regolith database",
                "no `regolith.db` marker",
                db_hint,
            ],
        )
        .unchanged(&random),
    );
    rows.push(
        row(
            "the folder above the database",
            &["inspect", s(&parent)],
            &[
                "is not a regolith database",
                "the folder below it is one: give",
                s(&inner),
            ],
        )
        .unchanged(&parent),
    );
    rows.push(
        row(
            "a database path that does not exist",
            &["validate", s(&t.join("nope.db"))],
            &[
                "nope.db",
                "is not a regolith database",
                "no such folder",
                db_hint,
            ],
        )
        .absent(&t.join("nope.db")),
    );

    // 10. `features repeat` without a mapping, or with a file holding something else.
    let img = regolith_tests::workspace_root().join("corpus/demo/captures/loc01_left_a.png");
    rows.push(row(
        "features repeat without --homography or --same-pose",
        &["features", "repeat", s(&img), s(&img)],
        &[
            "--homography FILE",
            "--same-pose",
            "nine numbers",
            "opencv-matrix",
        ],
    ));
    let h = t.join("h.txt");
    std::fs::write(&h, "1 0 3\n0 1 -2\n").unwrap();
    rows.push(row(
        "homography file holding something else",
        &[
            "features",
            "repeat",
            s(&img),
            s(&img),
            "--homography",
            s(&h),
        ],
        &["h.txt", "nine numbers", "opencv-matrix"],
    ));

    // More first-day mistakes. Rig balls named otherwise in a capture's Vicon file: found late
    // in the compile, after terrain objects were stored, which the failed compile takes back.
    let c = demo(t, "rig-names");
    let pose = c.join("vicon/loc02.csv");
    let text = std::fs::read_to_string(&pose).unwrap();
    std::fs::write(&pose, text.replace("Rig:Ball", "Rig:B")).unwrap();
    rows.push(
        row(
            "rig balls named otherwise in the rig-pose file",
            &["compile", s(&c), "--db", dbs],
            &[
                "capture \"loc02\"",
                "vicon/loc02.csv",
                "calib/rig_markers.csv",
                "Ball1",
                "Rig:B1",
                "name the balls in the Vicon file as in [rig].markers",
            ],
        )
        .unchanged(&db),
    );
    // The campaign folder (or any folder of other files) given as the new database.
    let c = demo(t, "db-in-campaign");
    rows.push(
        row(
            "a new database in a folder of other files",
            &["compile", s(&c), "--db", s(&c)],
            &[
                "db-in-campaign is neither a regolith database nor empty",
                "campaign.toml",
                "a new database needs a folder (or prefix) of its own; give a new name",
            ],
        )
        .unchanged(&c),
    );
    // Recompiling an edited campaign under the same release name; exporting into a folder
    // that is not empty.
    let c = demo(t, "same-version");
    rows.push(
        row(
            "release name and version already taken",
            &["compile", s(&c), "--db", dbs, "--release", "sample@1.0.0"],
            &[
                "release sample@1.0.0 already exists",
                "releases are immutable",
                "--release sample@1.0.1",
            ],
        )
        .unchanged(&db),
    );
    let full = t.join("full");
    std::fs::create_dir_all(&full).unwrap();
    std::fs::write(full.join("keep.txt"), "mine\n").unwrap();
    rows.push(
        row(
            "export into a folder that is not empty",
            &["export", dbs, "latest", "laser/0.05", "--to", s(&full)],
            &["full", "is not empty", "give a new folder"],
        )
        .unchanged(&db)
        .unchanged(&full),
    );
    // A physically rendered campaign whose renders are not in the cache, renderer forbidden.
    let empty_cache = t.join("no-renders");
    std::fs::create_dir_all(&empty_cache).unwrap();
    let camp = t.join("new-campaign");
    rows.push(
        row(
            "corpus generate with renders missing and --no-render",
            &[
                "corpus",
                "generate",
                "--seed",
                "301",
                "--renders",
                s(&empty_cache),
                "--no-render",
                "--out",
                s(&camp),
            ],
            &[
                "loc01_left",
                "no-renders",
                "tools/render/install.sh",
                "without --no-render",
            ],
        )
        .absent(&camp)
        .unchanged(&empty_cache),
    );

    let mut failures = Vec::new();
    for r in &rows {
        let before: Vec<_> = r.unchanged.iter().map(|d| snapshot(d)).collect();
        let out = Command::new(env!("CARGO_BIN_EXE_regolith"))
            .args(&r.args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let what = format!("{} (`regolith {}`)", r.mistake, r.args.join(" "));
        if out.status.code() != Some(2) {
            failures.push(format!(
                "{what}: exit {:?}, want 2\n{stderr}",
                out.status.code()
            ));
            continue;
        }
        for w in &r.words {
            if !stderr.contains(w.as_str()) {
                failures.push(format!("{what}: the message lacks {w:?}\n{stderr}"));
            }
        }
        for (d, b) in r.unchanged.iter().zip(&before) {
            if snapshot(d) != *b {
                failures.push(format!("{what}: changed {}", d.display()));
            }
        }
        for p in &r.absent {
            if p.exists() {
                failures.push(format!("{what}: created {}", p.display()));
            }
        }
        println!("{what}\n  {}", stderr.trim_end());
    }
    assert!(
        failures.is_empty(),
        "{} of {} rows failed:\n{}",
        failures.len(),
        rows.len(),
        failures.join("\n\n")
    );
}
