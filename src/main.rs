//! The `solidsynth` binary: exit code 2 for bad input, 1 for internal failures (the command
//! line itself lives in the library, behind the `cli` feature).

fn main() {
    solidsynth::cli::main();
}
