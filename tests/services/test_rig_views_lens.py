"""The rig page's calibration words say which lens each camera got (issue 35, item 2)."""

from __future__ import annotations

from saddlescope.core.types import LensModel
from saddlescope.io.rig_document import lens_model_to_dict
from saddlescope.services.rigs.views import calibration_words


def _calibration(models: dict[str, LensModel]) -> dict:
    return {"cameras": {n: {"rms_px": 0.2, "lens_model": lens_model_to_dict(m)} for n, m in models.items()},
            "checks": {"board_square_error_mm": 0.3}}


def test_a_held_lens_and_a_given_lens_are_said_in_words_a_joint_one_is_not():
    words = calibration_words(_calibration({
        "cam_0": LensModel(),
        "cam_1": LensModel(equal_focal=True, principal_point=False, joint=False),
        "cam_2": LensModel(given=True),
    }))["sentences"]
    lens = [s for s in words if "lens" in s and s.startswith("Camera")]
    assert len(lens) == 2
    assert lens[0].startswith("Camera cam_1's lens comes from its own views, in the simplest model they support "
                              "(one focal length for x and y, the principal point at the image centre)")
    assert lens[1].startswith("Camera cam_2's lens was given")
    assert not any("cam_0" in s for s in words)


def test_a_held_lens_with_every_parameter_fitted_names_no_fixed_parameter():
    words = calibration_words(_calibration({"c": LensModel(joint=False)}))["sentences"]
    assert "Camera c's lens comes from its own views: the other cameras' views would have bent it." in " ".join(words)
