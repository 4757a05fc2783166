//! Smoke test of the real `kage edit` window under Xvfb (tools/editor_smoke.sh): the window
//! opens on the built-in scene, bakes, and a screenshot of the X screen is not blank.
//! Needs Xvfb, xwd and python3 (`.ci/run` installs the first two); fails, never skips, without.

use std::process::Command;

#[test]
fn kage_edit_opens_a_window_that_is_not_blank() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let out = Command::new("bash")
        .arg(format!("{root}/tools/editor_smoke.sh"))
        .arg(env!("CARGO_BIN_EXE_kage"))
        .output()
        .expect("bash runs the smoke script");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(
        out.status.success(),
        "editor smoke test failed (needs Xvfb and xwd: apt-get install xvfb x11-apps):\n{text}"
    );
    assert!(text.contains("distinct colours"), "{text}");
}
