//! The `texsyn` command line; see `texsyn --help` and the `cli` module.

mod cli;

fn main() {
    std::process::exit(cli::main());
}
