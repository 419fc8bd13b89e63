//! `param load` / `param dump` end to end over a real pseudo-terminal against the virtual
//! board (`serve --pty`): a settings file is checked whole before anything is sent, taken
//! whole or not at all, and `dump` writes a file `load` takes back.

use host_sim::cmd::param::{self, get, resolve};
use host_sim::cmd::param_file;
use host_sim::cmd::serial::Link;
use host_sim::cmd::serve;
use host_sim::scenario::{Controller, Scenario};
use std::sync::mpsc;
use std::time::Duration;

fn start_board() -> String {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let r = serve::serve(&Scenario::default(), |p| tx.send(p.to_string()).unwrap());
        panic!("the virtual board stopped: {r:?}");
    });
    rx.recv_timeout(Duration::from_secs(10)).expect("PTY path")
}

fn value(port: &str, path: &str) -> f32 {
    let mut link = Link::open(port).unwrap();
    let pp = resolve(path, link.info.axes).unwrap();
    get(&mut link, pp).unwrap()
}

/// `param load` of `text`; the error as printed (`{e:#}`).
fn load(port: &str, text: &str) -> Result<(), String> {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("settings.toml");
    std::fs::write(&file, text).unwrap();
    param::run(&param::Args {
        port: port.to_string(),
        what: param::What::Load,
        path: Some(file.to_string_lossy().into_owned()),
        value: None,
        json: false,
    })
    .map_err(|e| format!("{e:#}"))
}

const KP: &str = "axis/0/kp_lsb_per_um";
const NULL1: &str = "axis/1/valve/null_lsb";
const MIN0: &str = "axis/0/limits/min_um";
const MAX0: &str = "axis/0/limits/max_um";

#[test]
fn load_is_checked_whole_taken_whole_and_dump_round_trips() {
    let port = start_board();
    let kp0 = value(&port, KP);
    let (min0, max0) = (value(&port, MIN0), value(&port, MAX0));
    assert!(min0 < max0);

    // One bad value among good ones: every problem named, the board not touched.
    let e = load(
        &port,
        &format!(
            "[axis.0]\nkp_lsb_per_um = {}\n[axis.1.valve]\nnull_lsb = 99999\n",
            kp0 * 2.0
        ),
    )
    .unwrap_err();
    let msg = e;
    assert!(msg.contains(NULL1) && msg.contains("nothing sent"), "{msg}");
    assert_eq!(value(&port, KP), kp0, "a refused file changed a value");

    // A good file: every value in force after it.
    load(
        &port,
        &format!("\"{KP}\" = {}\n[axis.1.valve]\nnull_lsb = -7\n", kp0 * 2.0),
    )
    .unwrap();
    assert_eq!(value(&port, KP), kp0 * 2.0);
    assert_eq!(value(&port, NULL1), -7.0);

    // A minimum above the old maximum, before the new maximum in the file: the board
    // refuses it alone, and takes it once the maximum is in force.
    let (min1, max1) = (max0 + 1000.0, max0 + 2000.0);
    load(
        &port,
        &format!("[axis.0.limits]\nmin_um = {min1}\nmax_um = {max1}\n"),
    )
    .unwrap();
    assert_eq!((value(&port, MIN0), value(&port, MAX0)), (min1, max1));

    // A set the board refuses whole (minimum above maximum, each value in range): the
    // error names the path, and every value changed on the way is put back.
    let e = load(
        &port,
        &format!(
            "\"{KP}\" = {}\n\"{NULL1}\" = 5\n[axis.0.limits]\nmin_um = {}\nmax_um = {}\n",
            kp0,
            min1 + 5000.0,
            min1 + 4000.0
        ),
    )
    .unwrap_err();
    let msg = e;
    assert!(
        msg.contains("nothing changed") && msg.contains("limits"),
        "{msg}"
    );
    assert_eq!(value(&port, KP), kp0 * 2.0);
    assert_eq!(value(&port, NULL1), -7.0);
    assert_eq!((value(&port, MIN0), value(&port, MAX0)), (min1, max1));

    // dump → load: the same values, and a changed one comes back.
    let dumped = {
        let mut link = Link::open(&port).unwrap();
        param_file::dump(&mut link).unwrap()
    };
    load(&port, &format!("\"{NULL1}\" = 11\n")).unwrap();
    assert_eq!(value(&port, NULL1), 11.0);
    load(&port, &dumped).unwrap();
    assert_eq!(value(&port, NULL1), -7.0);
    assert_eq!(value(&port, KP), kp0 * 2.0);
    let mut link = Link::open(&port).unwrap();
    assert_eq!(param_file::dump(&mut link).unwrap(), dumped);
    drop(link);

    // A tuned set (`tune --settings-out`) goes to the board in one command.
    let s = Scenario::default();
    let t = s
        .tuning
        .iter()
        .find(|t| t.period_us == 1000 && t.controller == Controller::Feedforward)
        .unwrap();
    load(&port, &param_file::from_tuning(&s, t, 0).unwrap()).unwrap();
    assert_eq!(value(&port, KP), t.axes["tangent"].kp_lsb_per_um);
}
