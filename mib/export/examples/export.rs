//! Writes one MIB export: `cargo run -p mib-export --example export -- <scos|xtce|json> <DIR>`.
//! (The ground tool's `ground mib export` does the same through `mib_export::write_all`.)
use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(fmt), Some(dir)) = (args.first(), args.get(1)) else {
        eprintln!("usage: export <scos|xtce|json> <DIR>");
        return ExitCode::from(2);
    };
    let format = match fmt.parse::<mib_export::Format>() {
        Ok(f) => f,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
    };
    match mib_export::write_all(format, &PathBuf::from(dir)) {
        Ok(paths) => {
            for p in paths {
                println!("{}", p.display());
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("cannot write {dir}: {e}");
            ExitCode::FAILURE
        }
    }
}
