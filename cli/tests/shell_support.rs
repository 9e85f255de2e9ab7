//! `regolith completions SHELL` and `regolith manpage`: generated from the same clap
//! definitions as the parser, so every command and option a user can type is completed and
//! documented. Checked against the real `--help` output, and by the shells and `man` themselves
//! where they are installed.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::process::Command;

use common::regolith;

/// The subcommands `regolith --help` lists.
fn subcommands() -> Vec<String> {
    let help = String::from_utf8(regolith(&["--help"]).stdout).unwrap();
    let list = help
        .split("Commands:")
        .nth(1)
        .unwrap()
        .split("Options:")
        .next()
        .unwrap();
    let names: Vec<String> = list
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|w| *w != "help")
        .map(str::to_string)
        .collect();
    assert!(names.len() >= 14, "{names:?}");
    names
}

#[test]
fn completions_cover_every_command_and_are_valid_bash() {
    for shell in ["bash", "zsh", "fish", "elvish", "powershell"] {
        let out = regolith(&["completions", shell]);
        assert!(out.status.success(), "{shell}");
        let script = String::from_utf8(out.stdout).unwrap();
        for cmd in subcommands() {
            assert!(script.contains(&cmd), "{shell} completion lacks {cmd}");
        }
        assert!(script.contains("texture-blur-m"), "{shell}: an option");
    }
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("regolith.bash");
    std::fs::write(&script, regolith(&["completions", "bash"]).stdout).unwrap();
    let bash = Command::new("bash")
        .arg("-n")
        .arg(&script)
        .output()
        .unwrap();
    assert!(
        bash.status.success(),
        "bash -n: {}",
        String::from_utf8_lossy(&bash.stderr)
    );
    let bad = regolith(&["completions", "tcsh"]);
    assert_eq!(bad.status.code(), Some(2));
}

#[test]
fn the_man_page_documents_every_command() {
    let out = regolith(&["manpage"]);
    assert!(out.status.success());
    let page = String::from_utf8(out.stdout).unwrap();
    assert!(
        page.starts_with(".ie") || page.contains(".TH regolith 1"),
        "{page:.200}"
    );
    for cmd in subcommands() {
        assert!(page.contains(&cmd), "regolith(1) lacks {cmd}");
    }
    let dir = tempfile::tempdir().unwrap();
    let out = regolith(&["manpage", "--dir", dir.path().to_str().unwrap()]);
    assert!(out.status.success());
    for cmd in subcommands() {
        let sub = std::fs::read_to_string(dir.path().join(format!("regolith-{cmd}.1")))
            .unwrap_or_else(|e| panic!("regolith-{cmd}.1: {e}"));
        assert!(sub.contains(&format!(".TH regolith-{cmd} 1")), "{cmd}");
    }
    let compile = std::fs::read_to_string(dir.path().join("regolith-compile.1")).unwrap();
    assert!(compile.contains("\\-\\-check") && compile.contains("\\-\\-db"));
    assert!(dir.path().join("regolith-corpus-generate.1").is_file());
    // Where `man` is installed it renders the page without warnings.
    if let Ok(man) = Command::new("man")
        .env("MANWIDTH", "80")
        .args(["--warnings", "-l"])
        .arg(dir.path().join("regolith-compile.1"))
        .output()
    {
        if man.status.success() {
            let text = String::from_utf8_lossy(&man.stdout);
            assert!(text.contains("--check"), "{text}");
        }
    }
}
