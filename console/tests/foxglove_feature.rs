//! A wheelcal built without the live Foxglove server (the console's cargo feature
//! `foxglove`, off by default) refuses `status --follow --foxglove` before it opens any
//! board, saying how to build one that has it; with the feature the server runs
//! (tests/foxglove_live.rs, CI's "Foxglove live server" step).

mod common;

#[cfg(not(feature = "foxglove"))]
#[test]
fn without_the_feature_foxglove_says_how_to_get_it() {
    // A port that does not exist: the refusal comes first, so it is never opened.
    let o = common::wheelcal()
        .args([
            "--port",
            "/nonexistent/wheelcal-port",
            "status",
            "--follow",
            "--foxglove",
        ])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("built without the live Foxglove server")
            && err.contains("cargo build --release -p wheelcal --features foxglove"),
        "{err}"
    );
    assert!(!err.contains("/nonexistent/wheelcal-port"), "{err}");
}

#[cfg(feature = "foxglove")]
#[test]
fn with_the_feature_foxglove_is_built_in() {
    const { assert!(wheelcal::foxglove_live::BUILT) };
    assert!(wheelcal::foxglove_live::require_built().is_ok());
}
