//! Writes the sample release into a database; used by the crash-safety tests, which run it with
//! `REGOLITH_FAILPOINT` set so it aborts between two steps of a commit.
//! Usage: `regolith-testwriter DB VERSION`.

use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    let (Some(db), Some(version)) = (args.get(1), args.get(2)) else {
        eprintln!("usage: regolith-testwriter DB VERSION");
        return ExitCode::from(2);
    };
    let result = regolith_reader::Writer::create_or_open(db)
        .map_err(regolith_tests::sample::SampleError::from)
        .and_then(|w| regolith_tests::sample::build(&w, version));
    match result {
        Ok(id) => {
            println!("{id}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
