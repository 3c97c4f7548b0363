"""Table 4.1 metrics: part instance mAP at IoU 0.5 and motion-type accuracy."""

from __future__ import annotations

import numpy as np
import pytest

from artic.errors import InputError
from artic.evaluation.segmentation import (
    Detections,
    average_precision,
    category_map,
    instance_iou,
    match_detections,
    mean_average_precision,
    motion_type_accuracy,
    motion_type_confusion,
    object_detections,
    pool,
)

GT = np.array([0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2])


def test_instance_iou_by_hand() -> None:
    pred = np.array([0, 0, 0, 1, 1, 1, 1, 1, 2, 2, 2, 2])
    iou = instance_iou(pred, GT)
    assert iou.shape == (3, 3)
    np.testing.assert_allclose(iou[0], [3 / 4, 0, 0])
    np.testing.assert_allclose(iou[1], [1 / 8, 4 / 5, 0])
    np.testing.assert_allclose(iou[2], [0, 0, 1])
    # points without a ground-truth part are ignored
    gt = GT.copy()
    gt[3] = -1
    assert instance_iou(pred, gt)[0, 0] == pytest.approx(1.0)


def test_perfect_prediction_has_ap_one_whatever_the_ids() -> None:
    pred = np.array([2, 0, 1])[GT]  # same parts, other ids
    det = object_detections(pred, np.array([0.5, 0.9, 0.1]), GT)
    assert det.true_positive.all() and det.n_ground_truth == 3
    assert average_precision(det) == 1.0
    assert mean_average_precision([det, det]) == 1.0
    assert mean_average_precision([det, det], pooled=False) == 1.0


def test_empty_prediction_has_ap_zero() -> None:
    det = Detections(np.zeros(0), np.zeros(0, dtype=bool), 3)
    assert average_precision(det) == 0.0
    assert np.isnan(average_precision(Detections(np.zeros(0), np.zeros(0, dtype=bool), 0)))


def test_hand_computed_ap() -> None:
    # 3 ground-truth parts; predictions by confidence: TP, FP, TP
    # precision 1, 1/2, 2/3 at recall 1/3, 1/3, 2/3 -> monotone precision 1, 2/3, 2/3
    # AP = 1/3 * 1 + 1/3 * 2/3 = 5/9
    det = Detections(np.array([0.9, 0.8, 0.7]), np.array([True, False, True]), 3)
    assert average_precision(det) == pytest.approx(5 / 9)
    # the order of the arrays does not matter, only the confidences
    shuffled = Detections(det.confidence[::-1].copy(), det.true_positive[::-1].copy(), 3)
    assert average_precision(shuffled) == pytest.approx(5 / 9)


def test_matching_takes_confidence_order_and_each_part_once() -> None:
    # two predictions overlap part 0 at IoU >= 0.5: the more confident one wins
    iou = np.array([[0.6, 0.0], [0.9, 0.0], [0.0, 0.4]])
    det = match_detections(iou, np.array([0.8, 0.3, 0.9]))
    assert det.true_positive.tolist() == [True, False, False]
    det = match_detections(iou, np.array([0.2, 0.3, 0.9]))
    assert det.true_positive.tolist() == [False, True, False]


def test_object_detections_end_to_end() -> None:
    # prediction 0 misses a point of part 0 (IoU 3/4), prediction 1 takes it (IoU 4/5),
    # part 2 is split in two halves (IoU 1/2 each: the first, more confident, matches)
    pred = np.array([0, 0, 1, 0, 1, 1, 1, 1, 2, 2, 3, 3])
    det = object_detections(pred, np.array([0.9, 0.8, 0.7, 0.6]), GT)
    assert det.true_positive.tolist() == [True, True, True, False]  # IoU 0.5 counts
    assert average_precision(det) == pytest.approx(1.0)
    # at threshold 0.76 only prediction 1 is right: AP = 1/3 * 1/2 (TP second)
    det = object_detections(pred, np.array([0.9, 0.8, 0.7, 0.6]), GT, threshold=0.76)
    assert det.true_positive.tolist() == [False, True, False, False]
    assert average_precision(det) == pytest.approx(1 / 6)


def test_pooled_and_per_object_map_differ_as_defined() -> None:
    good = Detections(np.array([0.9]), np.array([True]), 1)
    bad = Detections(np.array([0.95]), np.array([False]), 1)
    # per object: mean(1, 0) = 0.5; pooled: FP at 0.95 then TP at 0.9 -> precision 1/2 at
    # recall 1/2, AP = 1/4
    assert mean_average_precision([good, bad], pooled=False) == pytest.approx(0.5)
    assert mean_average_precision([good, bad]) == pytest.approx(0.25)
    assert pool([good, bad]).n_ground_truth == 2
    table = category_map({"drawer": [good], "lamp": [good, bad]})
    assert table == pytest.approx({"drawer": 1.0, "lamp": 0.25, "mean": 0.625})


def test_motion_type_accuracy_and_confusion() -> None:
    pred = np.array([0, 1, 2, 3, 1, 0])
    gt = np.array([0, 1, 2, 2, -1, 1])
    assert motion_type_accuracy(pred, gt) == pytest.approx(3 / 5)
    confusion = motion_type_confusion(pred, gt)
    assert confusion.sum() == 5 and np.trace(confusion) == 3
    assert confusion[2, 3] == 1 and confusion[1, 0] == 1


def test_bad_inputs_raise() -> None:
    with pytest.raises(InputError, match="part ids"):
        instance_iou(np.zeros(3, dtype=int), np.zeros(4, dtype=int))
    with pytest.raises(InputError, match="confidence"):
        object_detections(np.array([0, 1]), np.array([0.5]), np.array([0, 1]))
    with pytest.raises(InputError, match="motion types"):
        motion_type_accuracy(np.zeros(2, dtype=int), np.zeros(3, dtype=int))
