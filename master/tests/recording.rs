//! What a run sends to its observer: every k-th communication point with the first and the
//! last always included, how the run ended; and an SSP archive unpacked into a temporary
//! folder that is gone with the system. These tests need the packaged FMUs
//! (`scripts/build-fmus`).

mod common;

use common::{crane_sensor, run};
use spurio_master::ssp::SspVersion;
use spurio_master::System;
use spurio_master::TimeSeries;
use spurio_master::{RunEnd, RunOptions};

fn run_every(system: &System, output_interval: u64) -> (TimeSeries, RunEnd) {
    let options = RunOptions {
        output_interval,
        ..Default::default()
    };
    run(system, &options)
}

#[test]
fn an_output_interval_keeps_every_kth_point_and_the_last() {
    let system = crane_sensor(1.0, "U = 0.5");
    let (all, end) = run_every(&system, 1);
    assert_eq!(end, RunEnd::StopTime { time: 1.0 });
    assert_eq!(all.time.len(), 101);
    let (every7, _) = run_every(&system, 7);
    // 0, 7, …, 98 (15 points), then the stop time.
    assert_eq!(every7.time.len(), 16);
    for (i, (t, row)) in every7.time.iter().zip(&every7.rows).enumerate() {
        let k = if i == 15 { 100 } else { 7 * i };
        assert_eq!(*t, all.time[k]);
        assert_eq!(row, &all.rows[k], "point {k}");
    }
    assert_eq!(*every7.time.last().unwrap(), 1.0);
    // 0 means every point, as 1 does.
    assert_eq!(run_every(&system, 0).0.rows, all.rows);
}

#[test]
fn an_ssp_archive_is_unpacked_into_a_temporary_folder_removed_with_the_system() {
    let out = tempfile::tempdir().unwrap();
    let ssp = out.path().join("crane_sensor.ssp");
    crane_sensor(0.5, "U = 0.5")
        .export_ssp(&ssp, SspVersion::V1_0)
        .unwrap();
    let system = System::from_file(&ssp).unwrap();
    let unpacked = system.instances()[0].fmu.path.clone();
    assert!(unpacked.is_file());
    assert!(!unpacked.starts_with(out.path()), "{}", unpacked.display());
    assert_eq!(
        system.notes(),
        ["step size 0.01 from the org.spurio.simulation annotation (stepSize)"]
    );
    let copy = system.clone();
    drop(system);
    assert!(unpacked.is_file(), "a clone still uses the FMUs");
    let (series, _) = run_every(&copy, 1);
    assert_eq!(series.time.len(), 51);
    drop(copy);
    assert!(!unpacked.exists(), "{} is left behind", unpacked.display());
    // Unpacked where asked, it stays.
    let keep = out.path().join("kept");
    let system = System::from_file_unpacking(&ssp, Some(&keep)).unwrap();
    drop(system);
    assert!(keep.join("resources/GantryCrane.fmu").is_file());
    assert!(keep.join("resources/Sensor2.fmu").is_file());
    // Nothing is written next to the archive.
    assert!(!out.path().join("crane_sensor.ssp.d").exists());
}

#[test]
fn recording_nothing_reads_only_the_outputs_that_feed_connections() {
    let mut system = crane_sensor(1.0, "U = 0.5");
    let reads = |s: &System, i: usize| -> usize {
        s.plan().after_step[i].iter().map(|t| t.vrs.len()).sum()
    };
    // Recorded: crane.x (also a connection source), sensor.y[1], sensor.y_clean[1].
    assert_eq!((reads(&system, 0), reads(&system, 1)), (2, 2));
    let (recorded, _) = run_every(&system, 1);
    system.record_nothing().unwrap();
    assert!(system.plan().recorded.names.is_empty());
    // crane.x and crane.theta feed the sensor; nothing of the sensor is read.
    assert_eq!((reads(&system, 0), reads(&system, 1)), (2, 0));
    let (series, end) = run_every(&system, 1);
    assert_eq!(end, RunEnd::StopTime { time: 1.0 });
    assert_eq!(series.time, recorded.time);
    assert!(series.rows.iter().all(Vec::is_empty));
}
