//! The `solidsynth` binary's entry point: exit code 2 for bad input, 1 for internal failures.

use clap::Parser;

use super::{command_arguments, lapped, output, run, Cli, Command};

/// Run the command line named by the process's arguments; exits the process with its code.
pub fn main() {
    // Before any thread exists (see the function).
    crate::util::memory::limit_heap_arenas();
    // Mesa's implicit Vulkan layer VK_LAYER_MESA_device_select connects to the display server to
    // order the GPUs; on a headless machine (no XDG_RUNTIME_DIR) libwayland then prints "error:
    // XDG_RUNTIME_DIR is invalid or not set" on every start of a command that probes Vulkan. We
    // rank the adapters ourselves (`gpu::GpuContext::new`), so the layer is skipped unless the
    // user set NODEVICE_SELECT. (First thing in main: no other thread exists yet.)
    if std::env::var_os("NODEVICE_SELECT").is_none() {
        std::env::set_var("NODEVICE_SELECT", "1");
    }
    let args = Cli::parse();
    // The command's own arguments, for the check that no output is also an input
    // (`io::atomic::check_output_path`): a subcommand's name is not a path (`ptm capture -o
    // capture` writes ./capture).
    crate::io::atomic::set_command_arguments(command_arguments(
        std::env::args_os().skip(1).collect(),
    ));
    // llvmpipe's vector width (LP_NATIVE_VECTOR_WIDTH=512 on AVX-512 hosts unless set; 256
    // for the render, which crashes llvmpipe at 512), here for the same reason (parsing starts
    // no thread).
    use crate::gpu::context::{prepare_driver_environment_for, DriverUse};
    prepare_driver_environment_for(match &args.command {
        Command::Lapped(lapped::LappedCommand::Render(_)) => DriverUse::Rendering,
        _ => DriverUse::Compute,
    });
    // Output piped into a reader that quits early (`solidsynth eval ... | head`) ends the
    // process quietly, as for any Unix tool, instead of a panic in `println!` (Rust ignores
    // SIGPIPE by default). Files are unaffected: they are written to temporaries and renamed
    // before the summaries are printed. The server keeps ignoring it: a client that hangs up
    // must not stop it.
    #[cfg(unix)]
    if !matches!(args.command, Command::Serve(_)) {
        // SAFETY: restoring a signal's default disposition, before any other thread exists.
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        }
    }
    // An interrupted command leaves no partial output behind: outputs are written to
    // temporaries (renamed into place when complete), which the handler deletes.
    let _ = ctrlc::set_handler(|| {
        crate::io::atomic::discard_pending();
        std::process::exit(130);
    });
    let default_level = if args.quiet { "warn" } else { "info" };
    let default_filter = || format!("{default_level},wgpu_core=warn,wgpu_hal=warn,naga=warn");
    // A filter that does not parse is said once the log is up (it cannot log itself).
    let (filter, bad_filter) = match std::env::var("SOLIDSYNTH_LOG") {
        Ok(text) => match tracing_subscriber::EnvFilter::try_new(&text) {
            Ok(filter) => (filter, None),
            Err(e) => (default_filter().into(), Some((text, e))),
        },
        Err(_) => (default_filter().into(), None),
    };
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(output::LogWriter)
        .with_ansi(output::use_color())
        .without_time()
        .with_target(false)
        .init();
    if let Some((text, e)) = bad_filter {
        tracing::warn!("SOLIDSYNTH_LOG={text} ignored: not a log filter ({e})");
    }
    if let Err(e) = run(args) {
        // A benchmark's child that refused the user's values is the user's input too.
        let user = e
            .chain()
            .any(|c| c.is::<super::bench_child::ChildRefused>())
            || e.chain()
                .find_map(|c| c.downcast_ref::<crate::Error>())
                .is_some_and(|se| se.is_user_error());
        let causes: Vec<String> = e
            .chain()
            .map(|c| crate::error::without_os_code(&c.to_string()).into_owned())
            .collect();
        eprintln!("error: {}", causes.join(": "));
        std::process::exit(if user { 2 } else { 1 });
    }
}
