//! `parallax info`: version, features, GPU adapters.

use parallax::trace::Trace;

use crate::common::CommonArgs;

/// Arguments of `parallax info`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    common: CommonArgs,
}

/// Prints the version, the compiled features and every GPU adapter wgpu finds.
pub fn run(args: Args) -> parallax::Result<()> {
    let mut trace = Trace::new();
    println!("parallax {}", parallax::VERSION);
    println!("features: {}", parallax::features().join(", "));
    #[cfg(feature = "gpu")]
    {
        let spinner = args.common.spinner("looking for GPU adapters");
        let adapters = trace.time("gpu.enumerate", "info lists adapters", |_| {
            parallax::render::context::list_adapters()
        });
        spinner.finish_and_clear();
        if adapters.is_empty() {
            println!("GPU adapters: none (install a Vulkan driver, e.g. mesa-vulkan-drivers)");
        } else {
            println!("GPU adapters:");
            for a in adapters {
                println!("  {a}");
            }
        }
    }
    #[cfg(not(feature = "gpu"))]
    println!("GPU adapters: not compiled in (feature \"gpu\" is off)");
    args.common.finish(&trace)
}
