//! `host-sim --help` and every command's `--help` speak to a person: the main job is
//! named, and no rustdoc link (`` [`name`] ``) leaks into the text.

use std::process::Command;

fn help(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .arg("--help")
        .output()
        .unwrap();
    assert!(out.status.success(), "{args:?} --help failed");
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn help_names_the_main_job_and_carries_no_rustdoc_links() {
    let top = help(&[]);
    assert!(
        top.contains("Without a command it runs the main job"),
        "{top}"
    );
    let commands: Vec<String> = top
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .filter(|c| c != "help")
        .collect();
    assert!(commands.len() > 15, "{commands:?}");
    for c in &commands {
        let h = help(&[c]);
        for (n, line) in h.lines().enumerate() {
            assert!(
                !line.contains("[`") && !line.contains("crate::"),
                "host-sim {c} --help, line {}: {line}",
                n + 1
            );
        }
    }
}
