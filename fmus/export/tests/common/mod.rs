//! What the export-layer test suites (FMI 2.0 `export_layer.rs`, FMI 3.0 `fmi3_layer.rs`)
//! share.

/// Runs the test `child` of this test binary in a child process (with `SPURIO_PANIC_CHILD`
/// set, so that it does its work) and asserts that it passed and that the only line it wrote
/// on stderr is its own `child done`: a panic inside an FMU call prints nothing there.
pub fn assert_child_prints_only_its_line(child: &str) {
    let output = std::process::Command::new(std::env::current_exe().unwrap())
        .args(["--exact", child, "--nocapture", "--test-threads=1"])
        .env("SPURIO_PANIC_CHILD", "1")
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "child failed: {stdout}\n{stderr}");
    assert!(stdout.contains("1 passed"), "{stdout}");
    // the only line on stderr is the child's own
    assert_eq!(stderr.trim(), "child done", "{stderr}");
}
