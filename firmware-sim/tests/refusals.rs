//! Every way the device refuses a message over the link, each asserting the exact
//! [`Refusal`], and that a refused message leaves nothing half-applied.

mod common;

use firmware_sim::link::{Endpoint, HostMessage, LinkConfig, LinkError, Refusal, SimLink};
use firmware_sim::session::{SessionConfig, run_session};
use firmware_sim::{CAPACITY, Controller, DeviceConfig, DeviceError, host, reference};
use infer_core::{Dims, Error, FloatModel, Model, ModelKind, Quant, write_blob};
use sim::{Family, Task, Trajectory};

fn demo() -> Trajectory {
    common::pd_demo(&Family::POINT_GOAL.test_tasks()[0], 1)
}

fn point_goal_blob() -> Vec<u8> {
    reference::pd_point_goal_blob(Quant::F32, &[&demo()]).unwrap()
}

fn link() -> SimLink {
    SimLink::new(LinkConfig::default())
}

/// The reason `message` was refused (panics when it was acknowledged).
fn refusal(link: &mut SimLink, device: &mut dyn Endpoint, message: HostMessage<'_>) -> Refusal {
    match link.send(device, &message) {
        Err(LinkError::Refused { reason, .. }) => reason,
        other => panic!("{message:?} was not refused: {other:?}"),
    }
}

/// Asserts that uploading `blob` to a new device of `config` is refused as `DoesNotFit` and
/// leaves the device without a blob.
fn assert_upload_does_not_fit(blob: &[u8], config: DeviceConfig) {
    let mut device = firmware_sim::erased(config);
    let err = host::upload_blob(&mut link(), &mut device, blob).unwrap_err();
    assert!(
        matches!(
            err,
            LinkError::Refused {
                reason: Refusal::DoesNotFit,
                ..
            }
        ),
        "{err:?}"
    );
    assert_eq!(device.blob().err(), Some(DeviceError::NoBlob));
}

fn begin(blob: &[u8]) -> HostMessage<'static> {
    HostMessage::BlobBegin {
        len: blob.len() as u32,
        crc: infer_core::crc32(blob),
    }
}

#[test]
fn blob_messages_before_a_begin_are_not_ready() {
    let mut device = firmware_sim::erased(DeviceConfig::default());
    let mut link = link();
    let data = [1u8; 8];
    let early = [
        HostMessage::BlobChunk {
            offset: 0,
            data: &data,
        },
        HostMessage::BlobEnd,
        HostMessage::TeachBegin,
        HostMessage::TeachEnd,
    ];
    for message in early {
        assert_eq!(refusal(&mut link, &mut device, message), Refusal::NotReady);
    }
    assert_eq!(device.blob().err(), Some(DeviceError::NoBlob));
}

#[test]
fn the_application_refuses_bootloader_messages_as_not_ready() {
    let blob = point_goal_blob();
    let model = Model::from_bytes(&blob).unwrap();
    let mut controller = Controller::new(&model, DeviceConfig::default()).unwrap();
    let mut link = link();
    for message in [begin(&blob), HostMessage::BlobEnd] {
        assert_eq!(
            refusal(&mut link, &mut controller, message),
            Refusal::NotReady
        );
    }
}

#[test]
fn chunks_out_of_order_or_past_the_announced_length_are_refused() {
    let blob = point_goal_blob();
    let mut device = firmware_sim::erased(DeviceConfig::default());
    let mut link = link();
    link.send(&mut device, &begin(&blob)).unwrap();
    let skipped = HostMessage::BlobChunk {
        offset: 10,
        data: &blob[10..20],
    };
    assert_eq!(
        refusal(&mut link, &mut device, skipped),
        Refusal::OutOfOrder
    );
    let first = HostMessage::BlobChunk {
        offset: 0,
        data: &blob[..64],
    };
    link.send(&mut device, &first).unwrap();
    // The same chunk again under a new sequence number is not a duplicate but a rewind.
    assert_eq!(refusal(&mut link, &mut device, first), Refusal::OutOfOrder);
    let rest = HostMessage::BlobChunk {
        offset: 64,
        data: &blob[64..],
    };
    link.send(&mut device, &rest).unwrap();
    let beyond = HostMessage::BlobChunk {
        offset: blob.len() as u32,
        data: &[0],
    };
    assert_eq!(refusal(&mut link, &mut device, beyond), Refusal::OutOfOrder);
    // The refused chunks changed nothing: the blob still commits.
    link.send(&mut device, &HostMessage::BlobEnd).unwrap();
    assert_eq!(device.blob().unwrap(), &blob[..]);
}

#[test]
fn oversize_incomplete_corrupt_and_invalid_blobs_are_refused() {
    let blob = point_goal_blob();
    let mut device = firmware_sim::erased(DeviceConfig {
        flash_bytes: blob.len() - 1,
        ..DeviceConfig::default()
    });
    assert_eq!(
        refusal(&mut link(), &mut device, begin(&blob)),
        Refusal::BlobTooLarge
    );

    // Announced with another CRC; a short blob; a blob whose CRC matches but that is not a
    // valid model (magic changed before the CRC was taken).
    let mut not_a_model = blob.clone();
    not_a_model[0] = b'X';
    let wrong_crc = HostMessage::BlobBegin {
        len: blob.len() as u32,
        crc: infer_core::crc32(&blob) ^ 1,
    };
    let cases: [(HostMessage<'_>, &[u8]); 3] = [
        (wrong_crc, &blob),
        (begin(&blob), &blob[..blob.len() - 1]),
        (begin(&not_a_model), &not_a_model),
    ];
    for (announce, bytes) in cases {
        let mut device = firmware_sim::erased(DeviceConfig::default());
        let mut link = link();
        link.send(&mut device, &announce).unwrap();
        let chunk = HostMessage::BlobChunk {
            offset: 0,
            data: bytes,
        };
        link.send(&mut device, &chunk).unwrap();
        assert_eq!(
            refusal(&mut link, &mut device, HostMessage::BlobEnd),
            Refusal::BadBlob
        );
        assert_eq!(device.blob().err(), Some(DeviceError::NoBlob));
    }
}

#[test]
fn bad_transitions_and_an_empty_context_are_refused() {
    let mut link = link();
    let blob = point_goal_blob();
    let model = Model::from_bytes(&blob).unwrap();
    let mut controller = Controller::new(&model, DeviceConfig::default()).unwrap();
    link.send(&mut controller, &HostMessage::TeachBegin)
        .unwrap();
    // Nothing pushed yet: no latent to fix.
    assert_eq!(
        refusal(&mut link, &mut controller, HostMessage::TeachEnd),
        Refusal::BadTransition
    );
    let floats = |v: &[f32]| firmware_sim::link::Floats::from_slice(v).unwrap();
    let ok = [0.1f32, 0.2, 0.0, 0.0];
    let cases = [
        (floats(&ok[..3]), floats(&[0.0, 0.0]), floats(&ok)),
        (floats(&ok), floats(&[0.0, 0.0, 0.0]), floats(&ok)),
        (
            floats(&[f32::NAN, 0.0, 0.0, 0.0]),
            floats(&[0.0, 0.0]),
            floats(&ok),
        ),
        (floats(&ok), floats(&[f32::INFINITY, 0.0]), floats(&ok)),
        (
            floats(&ok),
            floats(&[0.0, 0.0]),
            floats(&[0.0, 0.0, 0.0, f32::NAN]),
        ),
    ];
    for (obs, action, next_obs) in cases {
        let message = HostMessage::Transition {
            obs,
            action,
            next_obs,
        };
        assert_eq!(
            refusal(&mut link, &mut controller, message),
            Refusal::BadTransition
        );
    }
    assert_eq!(controller.z(), None, "refused transitions taught nothing");
    // A good transition after the refusals still teaches.
    let good = HostMessage::Transition {
        obs: floats(&ok),
        action: floats(&[0.0, 0.0]),
        next_obs: floats(&ok),
    };
    link.send(&mut controller, &good).unwrap();
    link.send(&mut controller, &HostMessage::TeachEnd).unwrap();
    assert!(controller.z().is_some());
}

#[test]
fn a_valid_blob_the_device_cannot_run_is_refused_and_the_session_names_why() {
    // Wider than the compiled capacity (w8a32 keeps it within the flash budget).
    let dims = Dims {
        obs: 4,
        act: 2,
        r: 8,
        z: 4,
        hidden: CAPACITY + 2,
    };
    let wide = FloatModel::random(ModelKind::StateAction, dims, 3);
    let wide = write_blob(&wide, Quant::W8A32, &Default::default()).unwrap();
    assert_upload_does_not_fit(&wide, DeviceConfig::default());

    // Fits the capacity but not a small RAM budget.
    let blob = point_goal_blob();
    let tight = DeviceConfig {
        ram_bytes: 1024,
        ..DeviceConfig::default()
    };
    assert_upload_does_not_fit(&blob, tight);

    // A session reports the reason the device could not give over the wire.
    let task = Family::POINT_GOAL.test_tasks()[0];
    let d = demo();
    let config = SessionConfig {
        device: tight,
        ..SessionConfig::default()
    };
    let err = run_session(&blob, &task, &[&d], &config).unwrap_err();
    assert!(
        matches!(
            err,
            firmware_sim::SessionError::Device(DeviceError::RamBudget { budget: 1024, .. })
        ),
        "{err:?}"
    );
    let config = SessionConfig::default();
    let err = run_session(&wide, &Task::point_goal(0.0), &[&d], &config).unwrap_err();
    assert!(
        matches!(
            err,
            firmware_sim::SessionError::Device(DeviceError::Blob(Error::CapacityExceeded {
                capacity: CAPACITY,
                ..
            }))
        ),
        "{err:?}"
    );
}
