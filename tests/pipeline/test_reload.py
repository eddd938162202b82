"""A reload's hand-over between the threads, and which changes reopen the cameras."""

from __future__ import annotations

from trackerd.pipeline.reload import ReloadRequests, changes_calibration, changes_colours, source_settings


def test_a_rig_goes_to_the_processing_thread_then_to_the_publishing_thread(simulated_rig):
    requests = ReloadRequests()
    assert not requests.pending and requests.take_rig() is None and requests.take_outputs() is None
    older = simulated_rig.model_copy(update={"name": "older"})
    requests.request(older)
    requests.request(simulated_rig)  # the latest request wins
    assert requests.pending
    assert requests.take_outputs() is None  # not before the processing thread applied it
    assert requests.take_rig() is simulated_rig and requests.take_rig() is None
    assert not requests.pending
    requests.applied(simulated_rig)
    assert requests.pending
    assert requests.take_outputs() is simulated_rig and not requests.pending


def test_a_new_calibration_does_not_reopen_the_cameras_but_a_new_exposure_does(simulated_rig):
    left = simulated_rig.cameras[0]
    turned = left.model_copy(
        update={"extrinsics": left.extrinsics.model_copy(update={"yaw_deg": left.extrinsics.yaw_deg + 1.0})}
    )
    recalibrated = simulated_rig.model_copy(update={"cameras": (turned, *simulated_rig.cameras[1:])})
    assert source_settings(recalibrated) == source_settings(simulated_rig)
    assert changes_calibration(recalibrated, simulated_rig) and changes_colours(recalibrated, simulated_rig)

    exposure = left.acquisition.model_copy(update={"exposure_us": 2000.0})
    reexposed = simulated_rig.model_copy(
        update={"cameras": (left.model_copy(update={"acquisition": exposure}), *simulated_rig.cameras[1:])}
    )
    assert source_settings(reexposed) != source_settings(simulated_rig)

    renamed = simulated_rig.model_copy(update={"name": "another"})
    assert source_settings(renamed) == source_settings(simulated_rig)
    assert not changes_calibration(renamed, simulated_rig) and not changes_colours(renamed, simulated_rig)
