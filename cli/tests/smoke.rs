//! Smoke tests of the real `kage edit` window under Xvfb (tools/editor_smoke.sh): the window
//! opens, bakes, and a screenshot of the X screen is not blank; on a scene file, a click, Delete
//! and Ctrl+S sent by xdotool save the edit into the file.
//! Needs Xvfb, xwd, xdotool and python3 (`.ci/run` installs the first three); fails, never
//! skips, without.

use std::process::Command;

/// Runs the smoke script with `args` after the binary; returns its output.
fn smoke(args: &[&str]) -> String {
    // One window at a time: two editors baking on a 2-core runner slow each other's frames.
    static ONE_WINDOW: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _one = ONE_WINDOW.lock().unwrap_or_else(|e| e.into_inner());
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let out = Command::new("bash")
        .arg(format!("{root}/tools/editor_smoke.sh"))
        .arg(env!("CARGO_BIN_EXE_kage"))
        .args(args)
        .output()
        .expect("bash runs the smoke script");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(
        out.status.success(),
        "editor smoke test failed (needs Xvfb, xwd and xdotool: apt-get install xvfb x11-apps xdotool):\n{text}"
    );
    text
}

#[test]
fn kage_edit_opens_a_window_that_is_not_blank() {
    let text = smoke(&[]);
    assert!(text.contains("distinct colours"), "{text}");
}

#[test]
fn in_the_real_window_a_click_delete_and_ctrl_s_save_the_edit() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/scenes/cube_on_plane.gltf");
    let text = smoke(&["20", scene]);
    assert!(text.contains("saved the scene with 3 of 4 root nodes"), "{text}");
}
