//! Per-tick compute time on the simulated device, for random cheetah-sized policies (obs 17,
//! act 6, r 32, z 16) at hidden 64 and 128 and each quantization scheme:
//!
//! ```sh
//! cargo run -p firmware-sim --release --example tick_timing
//! ```
//!
//! Wall time on a shared host is noisy; `infer-core/examples/act_loop.rs` under callgrind
//! gives the repeatable instruction count per `act`.

use firmware_sim::link::{LinkConfig, SimLink};
use firmware_sim::{Controller, DeviceConfig, LoopConfig, host, run};
use infer_core::{Calibration, Dims, FloatModel, Model, ModelKind, Quant, write_blob};
use sim::{EnvConfig, Family, Trajectory, TransitionRef, make_env};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let family = Family::CHEETAH_VEL;
    let task = family.test_tasks()[10];
    let (obs, act) = (family.obs_dim(), family.act_dim());
    // A synthetic 20-step context: timing does not depend on the values.
    let mut context = Trajectory::new(0);
    let (s, a) = (vec![0.1f32; obs], vec![0.2f32; act]);
    for t in 0..20 {
        context.push(
            t,
            TransitionRef {
                obs: &s,
                action: &a,
                reward: 0.0,
                next_obs: &s,
                done: false,
            },
        );
    }
    let row = [s.as_slice(), &a, &s].concat();
    println!("| hidden | scheme | blob B | ticks | min us | median us | p99 us | max us |");
    println!("|---|---|---|---|---|---|---|---|");
    for hidden in [64, 128] {
        let float = FloatModel::random(
            ModelKind::StateAction,
            Dims {
                obs,
                act,
                r: 32,
                z: 16,
                hidden,
            },
            7,
        );
        let calibration = Calibration {
            contexts: vec![vec![vec![row.clone(); 20]]],
            observations: vec![s.clone(); 8],
        };
        for quant in [Quant::F32, Quant::W8A32, Quant::W8A8] {
            let blob = write_blob(&float, quant, &calibration)?;
            let config = DeviceConfig {
                flash_bytes: 256 * 1024,
                ..DeviceConfig::default()
            };
            let mut device = firmware_sim::erased(config);
            let mut link = SimLink::new(LinkConfig::default());
            host::upload_blob(&mut link, &mut device, &blob)?;
            let model = Model::from_bytes(device.blob()?)?;
            let mut controller = Controller::new(&model, config)?;
            host::teach(&mut link, &mut controller, &[&context], obs, act)?;
            let mut plant = make_env(
                family,
                EnvConfig {
                    horizon: Some(1000),
                    ..EnvConfig::default()
                },
            )?;
            let report = run(
                &mut controller,
                plant.as_mut(),
                &task,
                &LoopConfig::default(),
            )?;
            let (min, med, p99, max) = report.compute_percentiles();
            let us = |ns: u64| ns as f64 / 1e3;
            println!(
                "| {hidden} | {quant:?} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} |",
                blob.len(),
                report.records.len(),
                us(min),
                us(med),
                us(p99),
                us(max)
            );
        }
    }
    Ok(())
}
