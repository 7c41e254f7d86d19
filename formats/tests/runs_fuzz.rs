//! Runs files are typed by people: any text, and any mangling of a good file (circle rows
//! and laps included), is read or refused naming the file, never a panic; and every file
//! the reader accepts hands its rows on without a panic either.

use formats::runs_file::{Phase, RunsFile};
use proptest::prelude::*;
use std::path::Path;

const GOOD: &str = "test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase,laps\n\
umbmark,cw,4,0.080,0.052,,before,\n\
umbmark,ccw,4,-0.061,0.075,0.012,before,\n\
circle,cw,0.5,-0.198,-0.040,,before,2\n\
circle,ccw,0.5,-0.201,0.040,-0.4,after,3\n\
omni,4W-1,0.6,-0.052,0.011,0.021,,\n";

fn check(text: &str) -> Result<(), TestCaseError> {
    match RunsFile::parse(text, Path::new("fuzz.csv")) {
        Err(e) => prop_assert!(e.to_string().starts_with("fuzz.csv"), "{e}"),
        Ok(f) => {
            for phase in [Phase::Before, Phase::After] {
                let _ = f.umbmark(phase);
                let _ = f.omni(phase);
                for c in f.circles(phase) {
                    prop_assert!((1..=10).contains(&c.laps) && c.radius_m > 0.0, "{c:?}");
                }
            }
        }
    }
    Ok(())
}

proptest! {
    #[test]
    fn any_text_is_read_or_refused_by_name(text in "\\PC{0,400}") {
        check(&text)?;
    }

    #[test]
    fn a_mangled_good_file_is_read_or_refused_by_name(
        at in 0usize..GOOD.len(),
        with in prop::sample::select(vec!["", ",", "\n", "\"", "-", "0", "1e309", "NaN", "11", "circle", "x", "\r\n"]),
        cut in 0usize..GOOD.len(),
    ) {
        let mut text = GOOD.to_string();
        let at = (0..=at).rev().find(|i| text.is_char_boundary(*i)).unwrap_or(0);
        text.insert_str(at, with);
        let cut = cut.min(text.len());
        let cut = (0..=cut).rev().find(|i| text.is_char_boundary(*i)).unwrap_or(0);
        check(&text)?;
        check(&text[..cut])?;
    }
}

#[test]
fn the_good_file_reads_as_written() {
    let f = RunsFile::parse(GOOD, Path::new("fuzz.csv")).unwrap();
    assert_eq!(f.rows.len(), 5);
    assert_eq!(f.circles(Phase::Before).len(), 1);
    assert_eq!(f.circles(Phase::After)[0].laps, 3);
}
