//! The `solidsynth` binary: exit code 2 for bad input, 1 for internal failures.

mod cli;

use clap::Parser;

fn main() {
    let args = cli::Cli::parse();
    let default_level = if args.quiet { "warn" } else { "info" };
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("SOLIDSYNTH_LOG").unwrap_or_else(|_| {
                format!("{default_level},wgpu_core=warn,wgpu_hal=warn,naga=warn").into()
            }),
        )
        .with_writer(std::io::stderr)
        .without_time()
        .with_target(false)
        .init();
    if let Err(e) = cli::run(args) {
        let user = e
            .chain()
            .find_map(|c| c.downcast_ref::<solidsynth::Error>())
            .is_some_and(|se| se.is_user_error());
        eprintln!("error: {e:#}");
        std::process::exit(if user { 2 } else { 1 });
    }
}
