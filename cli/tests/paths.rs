//! Every command takes its paths in every form a user types: a bare name, `./x`, `../x`, an
//! absolute path, a symlink, a non-ASCII name, and a folder where a file is meant (`compile
//! DIR` finds `DIR/campaign.toml`). One table: (command, path form) → the command must not
//! fail on the path. Commands too slow to run in full here (`validate`, `gap`, `control`) are
//! run with an entry that does not exist: their database path was then opened, and the error
//! must be about the entry, not the path.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use regolith_reader::Writer;

/// A non-ASCII folder name (Latin diacritics and CJK).
const NON_ASCII: &str = "tërräin-数据";

/// The tree the table runs in:
/// `ws/data/terrain.db` (a database), `ws/data/link.db` → `terrain.db`,
/// `ws/data/<NON_ASCII>.db` (a copy), `ws/demo/` (the demo campaign), `ws/link-demo` →
/// `demo`, `ws/<NON_ASCII>/` (a copy of the campaign), `ws/sub/` (an empty folder to run from
/// for `../` forms), `ws/img/a.png`, `ws/img/h.xml`.
struct Tree {
    _tmp: tempfile::TempDir,
    ws: PathBuf,
}

fn tree() -> Tree {
    let tmp = tempfile::tempdir().unwrap();
    let ws = tmp.path().join("ws");
    let data = ws.join("data");
    std::fs::create_dir_all(&data).unwrap();
    let db = data.join("terrain.db");
    regolith_tests::sample::build(&Writer::create_or_open(&db).unwrap(), "1.0.0").unwrap();
    common::copy_dir(&db, &data.join(format!("{NON_ASCII}.db")));
    std::os::unix::fs::symlink("terrain.db", data.join("link.db")).unwrap();
    let root = regolith_tests::workspace_root();
    common::copy_dir(&root.join("corpus/demo"), &ws.join("demo"));
    common::copy_dir(&root.join("corpus/demo"), &ws.join(NON_ASCII));
    std::os::unix::fs::symlink("demo", ws.join("link-demo")).unwrap();
    std::fs::create_dir_all(ws.join("sub")).unwrap();
    std::fs::create_dir_all(ws.join("img")).unwrap();
    std::fs::copy(
        root.join("corpus/demo/captures/loc01_left_a.png"),
        ws.join("img/a.png"),
    )
    .unwrap();
    std::fs::write(
        ws.join("img/h.xml"),
        "<?xml version=\"1.0\"?>\n<opencv_storage>\n<H type_id=\"opencv-matrix\">\n  \
         <rows>3</rows>\n  <cols>3</cols>\n  <dt>d</dt>\n  <data>\n\t1. 0. 0.\n\t0. 1. 0.\n\t0. 0. 1. \
         </data></H>\n</opencv_storage>\n",
    )
    .unwrap();
    Tree { _tmp: tmp, ws }
}

fn run(cwd: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_regolith"))
        .current_dir(cwd)
        .args(args)
        .output()
        .unwrap()
}

/// The forms of one path: (label, working directory relative to `ws`, the path as typed).
/// `dir` is the folder holding the target relative to `ws`, `name` the target's name in it.
fn forms(ws: &Path, dir: &str, name: &str) -> Vec<(String, PathBuf, String)> {
    let abs = ws.join(dir).join(name);
    vec![
        ("bare name".into(), ws.join(dir), name.to_string()),
        ("./name".into(), ws.join(dir), format!("./{name}")),
        (
            "../dir/name".into(),
            ws.join("sub"),
            format!("../{dir}/{name}"),
        ),
        (
            "absolute".into(),
            PathBuf::from("/"),
            abs.to_str().unwrap().to_string(),
        ),
    ]
}

/// What a row expects.
enum Expect {
    /// Exit 0.
    Success,
    /// Exit 2 with an error that names this text and does not complain about a missing path.
    InputError(&'static str),
}

fn check(label: &str, cwd: &Path, args: &[&str], expect: &Expect) {
    let out = run(cwd, args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let context = format!(
        "{label}: `regolith {}` in {}",
        args.join(" "),
        cwd.display()
    );
    match expect {
        Expect::Success => assert!(
            out.status.success(),
            "{context}: exit {:?}\n{stderr}",
            out.status.code()
        ),
        Expect::InputError(words) => {
            assert_eq!(out.status.code(), Some(2), "{context}\n{stderr}");
            assert!(
                stderr.contains(words),
                "{context}: expected {words:?}\n{stderr}"
            );
            for bad in ["No such file", "not a regolith database"] {
                assert!(!stderr.contains(bad), "{context}: a path error\n{stderr}");
            }
        }
    }
}

#[test]
fn every_command_accepts_every_path_form() {
    let t = tree();
    let ws = &t.ws;
    let mut rows = 0;

    // Database paths: every form, plus a symlink and a non-ASCII name.
    let mut db_forms = forms(ws, "data", "terrain.db");
    db_forms.push(("symlink".into(), ws.join("data"), "link.db".into()));
    db_forms.push((
        "non-ASCII".into(),
        ws.join("data"),
        format!("{NON_ASCII}.db"),
    ));
    for (i, (form, cwd, db)) in db_forms.iter().enumerate() {
        let db = db.as_str();
        // The export folder in the same form as the database (absolute with the absolute one).
        let to = if Path::new(db).is_absolute() {
            ws.join(format!("data/exported-{i}"))
                .to_str()
                .unwrap()
                .to_string()
        } else {
            format!("exported-{i}")
        };
        let table: Vec<(&str, Vec<&str>, Expect)> = vec![
            ("verify", vec!["verify", db], Expect::Success),
            ("inspect", vec!["inspect", db, "latest"], Expect::Success),
            (
                "export",
                vec!["export", db, "latest", "laser/0.05", "--to", &to],
                Expect::Success,
            ),
            ("gc", vec!["gc", db], Expect::Success),
            (
                "release",
                vec!["release", db, "latest", "--publish", "--allow-uncertified"],
                Expect::Success,
            ),
            (
                "validate",
                vec!["validate", db, "--entry", "no/such-entry"],
                Expect::InputError("no/such-entry"),
            ),
            (
                "gap",
                vec!["gap", db, "--entry", "no/such-entry"],
                Expect::InputError("no/such-entry"),
            ),
            (
                "control",
                vec![
                    "control",
                    db,
                    "--entry",
                    "no/such-entry",
                    "--texture-blur-m",
                    "0.01",
                ],
                Expect::InputError("no/such-entry"),
            ),
        ];
        for (cmd, args, expect) in &table {
            check(&format!("{cmd} DB as {form}"), cwd, args, expect);
            rows += 1;
        }
        assert!(
            cwd.join(&to).join("height.png").is_file(),
            "export --to {to} as typed from {}",
            cwd.display()
        );
    }

    // Campaign paths: the file in every form, the folder in every form, a symlinked folder and
    // a non-ASCII folder; `--check` parses every file the campaign references.
    let mut campaign_forms = forms(ws, "demo", "campaign.toml");
    campaign_forms.extend(forms(ws, ".", "demo"));
    campaign_forms.push(("folder as .".into(), ws.join("demo"), ".".into()));
    campaign_forms.push((
        "symlinked folder".into(),
        ws.to_path_buf(),
        "link-demo".into(),
    ));
    campaign_forms.push((
        "symlinked folder's file".into(),
        ws.to_path_buf(),
        "link-demo/campaign.toml".into(),
    ));
    campaign_forms.push((
        "non-ASCII folder".into(),
        ws.to_path_buf(),
        NON_ASCII.into(),
    ));
    for (form, cwd, campaign) in &campaign_forms {
        check(
            &format!("compile --check CAMPAIGN as {form}"),
            cwd,
            &["compile", "--check", campaign],
            &Expect::Success,
        );
        rows += 1;
    }
    // One full compile, campaign and database both as bare names.
    check(
        "compile with bare names",
        &ws.join("demo"),
        &["compile", "campaign.toml", "--db", "built.db"],
        &Expect::Success,
    );
    assert!(ws.join("demo/built.db/refs").is_dir());
    rows += 1;

    // Image and homography paths.
    for (form, cwd, img) in forms(ws, "img", "a.png") {
        let h = if cwd.ends_with("img") {
            "h.xml".to_string()
        } else {
            img.replace("a.png", "h.xml")
        };
        check(
            &format!("features detect IMAGE as {form}"),
            &cwd,
            &["features", "detect", &img, "--detector", "fast"],
            &Expect::Success,
        );
        check(
            &format!("features repeat IMAGE --homography H as {form}"),
            &cwd,
            &[
                "features",
                "repeat",
                &img,
                &img,
                "--homography",
                &h,
                "--detector",
                "fast",
            ],
            &Expect::Success,
        );
        rows += 2;
    }

    // Output folders of the generators and of the man pages, as bare and non-ASCII names.
    for out in ["corpus-out", NON_ASCII] {
        let dir = ws.join("sub");
        check(
            &format!("corpus generate --out {out}"),
            &dir,
            &[
                "corpus",
                "generate",
                "--renderer",
                "model",
                "--seed",
                "1",
                "--out",
                out,
            ],
            &Expect::Success,
        );
        assert!(dir.join(out).join("campaign.toml").is_file(), "{out}");
        let man = format!("man-{out}");
        check(
            &format!("manpage --dir {man}"),
            &dir,
            &["manpage", "--dir", &man],
            &Expect::Success,
        );
        assert!(dir.join(&man).join("regolith-compile.1").is_file(), "{man}");
        rows += 2;
    }
    assert_eq!(rows, 73, "every row of the table ran");
}
