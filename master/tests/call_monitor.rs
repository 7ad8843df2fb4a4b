//! The call monitor names the FMI call that does not return: an FMU whose `fmi2DoStep` never
//! returns at t = 0.03 (`fixtures/misbehaving.c`) runs on a thread of its own while this one
//! watches. (That thread stays stuck in the FMU until this test binary ends, so this file
//! holds this one test.)

mod common;

use spurio_master::fmu::LoadOptions;
use spurio_master::NoRecording;
use spurio_master::{CallMonitor, RunOptions, Simulation};
use spurio_master::{System, SystemDescription};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[test]
fn the_monitor_names_the_instance_the_call_and_the_time_of_a_call_that_does_not_return() {
    let dir = std::env::temp_dir().join(format!("spurio-monitor-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fmu = common::misbehaving_fmu(&dir);
    std::env::set_var("MISBEHAVE", "hang");
    std::env::set_var("MISBEHAVE_AT", "0.03");
    let description: SystemDescription = toml::from_str(
        "stop_time = 0.1\nstep_size = 0.01\nrecord = [\"crane.x\"]\n\
         [[instance]]\nname = \"crane\"\nfmu = \"Bad.fmu\"\n",
    )
    .unwrap();
    // Unpacked into the test's folder, which goes at the end (the stuck thread never drops
    // the FMU).
    let options = LoadOptions {
        temp_dir: Some(dir.clone()),
        ..LoadOptions::default()
    };
    let system = System::resolve_loading(&description, &dir, &options).unwrap();
    let monitor = Arc::new(CallMonitor::default());
    {
        let monitor = monitor.clone();
        std::thread::spawn(move || {
            let mut sim = Simulation::with_monitor(&system, Some(monitor)).unwrap();
            let _ = sim.run(&mut NoRecording, &RunOptions::default());
        });
    }
    let deadline = Instant::now() + Duration::from_secs(30);
    let call = loop {
        assert!(Instant::now() < deadline, "no call stayed in progress");
        match monitor.current() {
            Some(c) if c.since.elapsed() > Duration::from_millis(300) => break c,
            _ => std::thread::sleep(Duration::from_millis(10)),
        }
    };
    assert_eq!(call.instance, "crane");
    assert_eq!(call.file, fmu.display().to_string());
    assert_eq!(call.call, "fmi2DoStep");
    assert!((call.time - 0.03).abs() < 1e-12, "{}", call.time);
    assert_eq!(
        call.to_string(),
        format!(
            "instance `crane` ({}): fmi2DoStep at t = {}",
            fmu.display(),
            call.time
        )
    );
    // Still in that call: the monitor is not left behind by the calls before.
    std::thread::sleep(Duration::from_millis(50));
    assert_eq!(monitor.current().map(|c| c.since), Some(call.since));
    std::fs::remove_dir_all(&dir).unwrap();
}
