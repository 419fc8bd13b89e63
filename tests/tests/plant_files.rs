//! The shipped scenario and table, and the error paths of scenario and table files.

use host_sim::camfile::CamCsv;
use host_sim::die::DieTable;
use host_sim::scenario::{Role, Scenario, ScenarioError};
use std::path::{Path, PathBuf};

fn scenarios() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios")
}

/// `tangent_table.csv` is exactly the elliptical-die generator's output. To regenerate it
/// after changing the generator: `HOST_SIM_WRITE_TABLE=1 cargo test -p hydra-tests --test
/// plant_files shipped_table`.
#[test]
fn shipped_table_is_the_die_formula() {
    let path = scenarios().join("tangent_table.csv");
    let want = DieTable::default().table().to_csv();
    if std::env::var_os("HOST_SIM_WRITE_TABLE").is_some() {
        std::fs::write(&path, &want).unwrap();
    }
    let got = std::fs::read_to_string(&path).unwrap();
    assert_eq!(got, want, "{} differs from the die formula", path.display());
    let t = CamCsv::load(&path).unwrap();
    assert_eq!(t.axes, ["tangent"]);
    assert_eq!(t.master.len(), 181);
    assert_eq!((t.master[0], t.master[180]), (0.0, 90.0));
    let x = t.column("tangent").unwrap();
    let lo = x.iter().copied().fold(f64::MAX, f64::min);
    let hi = x.iter().copied().fold(f64::MIN, f64::max);
    assert_eq!((lo, hi), (20.0, 480.0));
}

/// `tangent.toml` spells out the reference machine: it equals the defaults.
#[test]
fn shipped_scenario_is_the_reference_machine() {
    let s = Scenario::load(&scenarios().join("tangent.toml")).unwrap();
    assert_eq!(s.name(), "tangent");
    let d = Scenario::default();
    assert_eq!(s.sim, d.sim);
    assert_eq!(s.supply, d.supply);
    assert_eq!(s.master, d.master);
    assert_eq!(s.axes.len(), 2);
    assert_eq!(s.axes[0].cylinder, d.axes[0].cylinder);
    assert_eq!(s.axes[0].valve, d.axes[0].valve);
    assert_eq!(s.axes[1].role, Role::Force);
    assert_eq!(s.axes[1].cylinder, d.axes[1].cylinder);
    assert_eq!(s.axes[1].contact, d.axes[1].contact);
    let t = s.load_table(None).unwrap();
    assert_eq!(t.columns, DieTable::default().table().columns);
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn scenario_error_paths() {
    let dir = tempfile::tempdir().unwrap();
    let load = |text: &str| {
        Scenario::load(&write(dir.path(), "s.toml", text))
            .unwrap_err()
            .to_string()
    };
    let e = Scenario::load(&dir.path().join("missing.toml")).unwrap_err();
    assert!(matches!(e, ScenarioError::Io { .. }), "{e}");
    let e = load("[sim\n");
    assert!(e.contains("s.toml") && e.contains("line 1"), "{e}");
    let e = load("[master]\nspeed = 3\n");
    assert!(
        e.contains("unknown field `speed`") && e.contains("line 2"),
        "{e}"
    );
    let e = load("[[axis]]\nname = \"t\"\n[axis.valve]\ndamping = -1\n");
    assert!(e.contains("`axis.t.valve.damping` = -1"), "{e}");
    let e = load("[[axis]]\nname = \"t\"\n[axis.cylinder]\nmass_kg = 0.001\n");
    assert!(e.contains("`sim.step_us`") && e.contains("axis `t`"), "{e}");
    let s = Scenario::load(&write(
        dir.path(),
        "s1.toml",
        "[table]\nfile = \"nope.csv\"\n",
    ))
    .unwrap();
    let e = s.load_table(None).unwrap_err().to_string();
    assert!(
        e.contains("cannot read table") && e.contains("nope.csv"),
        "{e}"
    );
    // A table without the follower's column.
    write(dir.path(), "t.csv", "master,other\n0,1\n1,2\n");
    let s = Scenario::load(&write(dir.path(), "s2.toml", "[table]\nfile = \"t.csv\"\n")).unwrap();
    let e = s.load_table(None).unwrap_err().to_string();
    assert!(
        e.contains("`axis.tangent.name`") && e.contains("columns: other"),
        "{e}"
    );
}

#[test]
fn table_error_paths_name_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let load = |text: &str| {
        CamCsv::load(&write(dir.path(), "bad.csv", text))
            .unwrap_err()
            .to_string()
    };
    assert!(load("master,tangent\n0,20\n0.5,21\n0.5,22\n").contains("bad.csv:4: master 0.5"));
    assert!(load("master,tangent\n0,20\n0.5,abc\n").contains("bad.csv:3: column `tangent`"));
    assert!(load("angle,tangent\n").contains("bad.csv:1: header must start with `master`"));
    assert!(load("# x\n\nmaster,tangent\n0,1\n1\n").contains("bad.csv:5: 1 fields"));
    let e = CamCsv::load(&dir.path().join("none.csv"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cannot read table"), "{e}");
}
