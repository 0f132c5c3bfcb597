//! `opennav`: the chair's command line and daemon (see `cli/`).

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
