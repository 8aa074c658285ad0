//! The quickstart's last stage: the blob on a simulated device (firmware-sim), flashed over a
//! lossy link, taught one test demo, run in the fixed-rate loop.

use std::path::Path;

use firmware_sim::link::{LinkConfig, SimLink};
use firmware_sim::{Controller, DeviceConfig, LoopConfig, host, ram_needed, trace};
use sim::DemoDataset;

use super::{DeviceSensing, Quickstart, device_err, io, write};
use trainer::Result;
use trainer::eval;

/// Runs the blob on the simulated device, taught the first demo of test task `index`.
pub(super) fn device_run(
    args: &Quickstart<'_>,
    blob: &[u8],
    test: &DemoDataset,
    dir: &Path,
) -> Result<firmware_sim::RunReport> {
    let task = args.env.test_tasks()[3 % args.env.test_tasks().len()];
    let demo = eval::contexts_for(test, args.env, &[task])?[0].trajectories[0].clone();
    let config = DeviceConfig::default();
    let mut device = firmware_sim::erased(config);
    let mut link = SimLink::new(LinkConfig {
        corrupt_probability: 0.01,
        seed: args.seed,
        ..LinkConfig::default()
    });
    host::upload_blob(&mut link, &mut device, blob).map_err(device_err)?;
    let model =
        infer_core::Model::from_bytes(device.blob().map_err(device_err)?).map_err(device_err)?;
    let mut controller = Controller::new(&model, config).map_err(device_err)?;
    host::teach(
        &mut link,
        &mut controller,
        &[&demo],
        test.obs_dim,
        test.act_dim,
    )
    .map_err(device_err)?;
    let z = controller.z().map(<[f32]>::to_vec).unwrap_or_default();
    let mut plant = sim::make_env(args.env, args.env_config())?;
    let loop_config = LoopConfig {
        sensing: match args.sensing {
            DeviceSensing::Full => firmware_sim::Sensing::Full,
            DeviceSensing::Positions => firmware_sim::Sensing::POSITIONS,
        },
        seed: args.seed,
        noise_std: 0.005,
        adc_bits: Some(12),
        adc_range: 4.0,
        ..LoopConfig::default()
    };
    let report = firmware_sim::run(&mut controller, plant.as_mut(), &task, &loop_config)
        .map_err(device_err)?;
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let csv = dir.join("trace.csv");
    trace::write_csv(&csv, &report, &z).map_err(io(&csv))?;
    trace::write_plot(&dir.join("plot.svg"), &report).map_err(device_err)?;
    let summary = trace::summary(
        &report,
        blob.len(),
        config.flash_bytes,
        ram_needed(),
        config.ram_bytes,
    );
    write(&dir.join("summary.txt"), format!("{summary}\n"))?;
    eprintln!(
        "{}",
        summary
            .lines()
            .map(|l| format!("  {l}"))
            .collect::<Vec<_>>()
            .join("\n")
    );
    Ok(report)
}
