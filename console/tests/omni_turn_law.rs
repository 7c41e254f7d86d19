//! `factors set --l-arc` on an omni board, through the `wheelcal` binary: the turn law
//! joins the board's factors without touching them, reads back in words and JSON, and is
//! refused beside differential factors or out of range.

mod common;

use common::{json_of, scratch, Board};

#[test]
fn an_omni_boards_turn_law_is_set_shown_and_refused_in_words() {
    let dir = scratch("omni-law");
    let board = Board::start("omni3", &dir);
    let (o, _, err) = board.run_text(&[
        "factors",
        "set",
        "--f-lat",
        "1.01,0.99,1",
        "--f-lon",
        "1.02",
    ]);
    assert!(o.status.success(), "{err}");
    // --l-arc alone keeps F_lat and F_lon.
    let (o, out, err) = board.run_text(&["factors", "set", "--l-arc", "0.019"]);
    assert!(o.status.success(), "{err}");
    assert!(
        out.contains("F_lat = [1.010000, 0.990000, 1.000000]  F_lon = 1.020000  L_arc = +0.0190: the wheels' distance from the centre 1.9 % longer on arcs"),
        "{out}"
    );
    let f = json_of(&board.run(&["--json", "factors", "get"]));
    assert_eq!(f["kind"], "omni", "{f}");
    assert_eq!(f["l_arc"], 0.019, "{f}");
    assert_eq!(f["f_lon"], 1.02, "{f}");
    let (o, _, err) = board.run_text(&["factors", "set", "--l-arc", "0.2"]);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("l_arc = 0.2 is outside [-0.1, 0.1]"), "{err}");
    let (o, _, err) = board.run_text(&["factors", "set", "--l-arc", "0.01", "--e-b", "1"]);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("do not mix"), "{err}");
    // Refused sets changed nothing; --l-arc 0 removes the law.
    let f = json_of(&board.run(&["--json", "factors", "set", "--l-arc", "0"]));
    assert!(f.get("l_arc").is_none(), "{f}");
    assert_eq!(f["f_lat"], serde_json::json!([1.01, 0.99, 1.0]), "{f}");
}
