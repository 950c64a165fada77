//! The `foldmatch` command: everything is in [`foldmatch::cli`] (also used by the Python
//! console script), so that there is one implementation.

fn main() {
    std::process::exit(foldmatch::cli::run(std::env::args_os()));
}
