"""Box geometry (vtrack/boxes.py) against areas worked out by hand."""

import numpy as np

from vtrack.boxes import (centre, clip, contains, edges, enclosing, enclosing_each, from_centre,
                          in_image, intersection, iou, on_border, overlap_of_smaller,
                          paired_iou, scale)


def test_paired_iou_of_hand_worked_pairs():
    a = np.array([[0, 0, 10, 10], [0, 0, 10, 10], [0, 0, 10, 10], [5, 5, 2, 2]], float)
    b = np.array([[0, 0, 10, 10], [5, 0, 10, 10], [20, 20, 5, 5], [0, 0, 10, 10]], float)
    # identical; half shifted: 50 / (100 + 100 - 50); disjoint; nested: 4 / 100
    assert np.allclose(paired_iou(a, b), [1.0, 50 / 150, 0.0, 0.04])
    assert np.allclose(intersection(a, b), [100, 50, 0, 4])


def test_iou_matrix_is_the_pairs_of_every_row_and_column():
    rng = np.random.default_rng(0)
    a = np.column_stack([rng.uniform(0, 50, (5, 2)), rng.uniform(1, 30, (5, 2))])
    b = np.column_stack([rng.uniform(0, 50, (7, 2)), rng.uniform(1, 30, (7, 2))])
    m = iou(a, b)
    assert m.shape == (5, 7)
    for i in range(5):
        assert np.allclose(m[i], paired_iou(np.repeat(a[i:i + 1], 7, axis=0), b))
    assert np.allclose(iou(b, a), m.T)


def test_overlap_of_smaller_and_degenerate_boxes():
    box = np.array([0, 0, 10, 10], float)
    others = np.array([[2, 2, 4, 4], [5, 5, 10, 10], [0, 0, 0, 0]], float)
    assert np.allclose(overlap_of_smaller(box, others), [1.0, 25 / 100, 0.0])
    assert paired_iou(np.zeros(4), np.zeros(4)) == 0.0   # two empty boxes: no overlap


def test_enclosing_each_is_enclosing_of_each_row_bit_for_bit():
    rng = np.random.default_rng(1)
    boxes = np.column_stack([rng.uniform(-20, 50, (6, 2)), rng.uniform(0.1, 30, (6, 2))])
    member = rng.random((40, 6)) < 0.4
    member = member[member.any(axis=1)]
    each = enclosing_each(boxes, member)
    for row, chosen in zip(each, member, strict=True):
        assert row.tobytes() == enclosing(boxes[chosen]).tobytes()
    assert enclosing_each(boxes, np.zeros((0, 6), bool)).shape == (0, 4)
    assert enclosing_each(np.zeros((0, 4)), np.zeros((0, 0), bool)).shape == (0, 4)


def test_clip_cuts_boxes_to_the_image():
    boxes = np.array([[-5, -5, 10, 10], [630, 350, 20, 20], [700, 0, 10, 10]], float)
    assert np.allclose(clip(boxes, 640, 360),
                       [[0, 0, 5, 5], [630, 350, 10, 10], [640, 0, 0, 10]])


def test_centre_edges_scale_of_hand_worked_boxes():
    b = np.array([[10, 20, 40, 10], [0, 0, 9, 4]], float)
    assert np.array_equal(centre(b), [[30, 25], [4.5, 2]])
    assert np.array_equal(edges(b), [[10, 20, 50, 30], [0, 0, 9, 4]])
    assert np.array_equal(scale(b), [20, 6])
    assert np.array_equal(from_centre(centre(b), b[:, 2:]), b)
    assert np.array_equal(centre(b[0]), [30, 25])             # one box (4,)


def test_in_image_and_on_border_of_a_100_x_50_picture():
    b = np.array([[0, 0, 100, 50], [-1, 10, 20, 20], [80, 30, 20.4, 20], [10, 10, 5, 5]])
    assert in_image(b, 100, 50).tolist() == [True, False, False, True]
    cut = on_border(b, 100, 50)          # (box, axis x/y, low/high edge)
    assert cut[0].all()
    assert cut[1].tolist() == [[True, False], [False, False]]
    assert cut[2].tolist() == [[False, True], [False, True]]
    assert not cut[3].any()


def test_contains_takes_the_left_and_top_edges_not_the_right_and_bottom():
    boxes = np.array([[0.0, 0.0, 10.0, 5.0], [5.0, 5.0, 2.0, 2.0]])
    points = np.array([[0.0, 0.0], [9.9, 4.9], [10.0, 2.0], [6.0, 6.0], [3.0, 5.0]])
    assert contains(boxes, points).tolist() == [[True, True, False, False, False],
                                                [False, False, False, True, False]]
