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
    })).sentences
    lens = [s for s in words if "lens" in s and s.startswith("Camera")]
    assert len(lens) == 2
    assert lens[0].startswith("Camera cam_1's lens comes from its own views, in the simplest model they support "
                              "(one focal length for x and y, the principal point at the image centre)")
    assert lens[1].startswith("Camera cam_2's lens was given")
    assert not any("cam_0" in s for s in words)


def test_a_held_lens_with_every_parameter_fitted_names_no_fixed_parameter():
    words = calibration_words(_calibration({"c": LensModel(joint=False)})).sentences
    assert "Camera c's lens comes from its own views: the other cameras' views would have bent it." in " ".join(words)


def test_whether_a_wand_refined_the_board_is_said_in_words():
    """Issue 35: a board+wand calibration says whether the wand's refinement was kept, and why not."""
    from saddlescope.core.types import Rig, WandCheck, WandRefinement
    from saddlescope.io.rig_document import rig_to_dict

    board = WandCheck(84.2, 0.03, 0.136, {"left": 575.0, "middle": 214.0, "right": 524.0})
    refined = WandCheck(3.9, 0.08, 0.138, {"left": 632.0, "middle": 633.0, "right": 636.0})
    cameras = _rig_cameras()
    for choice, says, kept in (
            (WandRefinement(True, "no worse", 1000.0, 42, board, refined),
             "Refined by the wand: the middle camera's lens is now known to 633 px from the centre of its image, "
             "was 214 px; the wand's length on 42 frames it did not fit is off by 3.9 mm r.m.s., was 84.2 mm.", True),
            (WandRefinement(False, "with the wand the board's squares came out 0.22 % r.m.s. off", 1000.0, 42, board,
                            WandCheck(9.8, 0.22, 0.16, refined.reach_px)),
             "Not refined by the wand: with the wand the board's squares came out 0.22 % r.m.s. off. The board's "
             "calibration is kept.", False)):
        words = calibration_words(rig_to_dict(Rig(cameras, checks={"board_square_error_mm": 0.02},
                                                  wand_refinement=choice)))
        assert says in words.sentences and words.refined_by_wand is kept
    assert calibration_words(_calibration({"c": LensModel()})).refined_by_wand is None  # no wand offered


def _rig_cameras() -> dict:
    import numpy as np

    from saddlescope.core.types import Camera

    K = np.array([[900.0, 0, 640], [0, 900, 360], [0, 0, 1]])
    return {n: Camera(n, K, np.zeros(5), (1280, 720), t_mm=np.array([i * 1800.0, 0, 0]))
            for i, n in enumerate(("left", "middle", "right"))}
