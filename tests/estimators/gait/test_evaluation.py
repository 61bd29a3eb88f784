"""stridelab.estimators.gait.evaluation.event_accuracy: spans and unscored spans (the scorer of the gait stage and bench)."""
import numpy as np
import pytest

from stridelab.estimators.gait.evaluation import event_accuracy


def test_unscored_spans_move_unmatched_detections_out_of_the_false_positives():
    ref = [np.array([1.0, 2.0, 3.0, 4.0])]
    det = [np.array([1.02, 2.01, 2.5, 3.03, 3.6, 4.0])]          # 2.5 and 3.6 match nothing
    plain = event_accuracy(det, ref, tolerance_s=0.1)
    assert (plain.tp, plain.fp, plain.fn, plain.unscored) == (4, 2, 0, 0)
    part = event_accuracy(det, ref, tolerance_s=0.1, unscored_spans_s=[[(2.2, 2.8)]])
    assert (part.tp, part.fp, part.unscored) == (4, 1, 1)
    assert part.precision == pytest.approx(4 / 5) and plain.precision == pytest.approx(4 / 6)
    # a matched detection inside an unscored span stays a true positive; the span's edges are open
    edge = event_accuracy(det, ref, tolerance_s=0.1, unscored_spans_s=[[(2.5, 3.6)]])
    assert (edge.tp, edge.fp, edge.unscored) == (4, 2, 0)
    with pytest.raises(ValueError):
        event_accuracy(det, ref, unscored_spans_s=[])
