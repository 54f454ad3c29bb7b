"""Per-sample contact flags and point of contact (pipeline.engines.common.ContactFlags): the POC of
a sample is each whisker's most proximal contact at its last step with contacts in the interval."""

import numpy as np

from pipeline.engines.common import ContactFlags


def _link_points(flat_links, fraction_on_link, links=4):
    """Contacts on straight links of unit length along x: link n from x = n to x = n + 1."""
    link = np.asarray(flat_links) % links
    proximal = np.column_stack([link, np.zeros(len(link)), np.zeros(len(link))]).astype(float)
    distal = proximal + [1.0, 0.0, 0.0]
    points = proximal + np.asarray(fraction_on_link)[:, None] * (distal - proximal) + [0.0, 0.3, 0.0]
    return np.asarray(flat_links), points, proximal, distal


def test_each_whisker_keeps_its_last_contact_step_and_a_new_interval_starts_empty():
    fractions = np.tile(np.linspace(0.0, 1.0, 5), (3, 1))          # 3 whiskers, 4 equal links
    flags = ContactFlags(fractions)
    flags.add(*_link_points([0 * 4 + 1, 1 * 4 + 3], [0.5, 0.5]))      # whiskers 0 and 1
    flags.add(*_link_points([0 * 4 + 3, 0 * 4 + 2], [0.0, 0.5]))      # whisker 0 again: its last step
    flags.add(*_link_points([], []))                                  # a step without contacts changes nothing
    touching, poc = flags.take()
    assert poc.dtype == np.float32
    assert np.allclose(poc, [0.625, 0.875, np.nan], equal_nan=True)  # link 2 at half: (2 + 0.5) / 4
    assert touching.tolist() == [[False, True, True, True], [False, False, False, True], [False] * 4]
    touching, poc = flags.take()
    assert not touching.any() and np.isnan(poc).all()


def test_steps_added_stacked_are_the_steps_added_one_by_one():
    """The compiled runs hand back their steps' contacts stacked (ContactFlags.add_stacked): the
    same flags and POC as the steps added in turn, a step without contacts counting for none."""
    fractions = np.tile(np.linspace(0.0, 1.0, 5), (3, 1))
    steps = [([0 * 4 + 1, 1 * 4 + 3], [0.5, 0.5]), ([], []), ([0 * 4 + 3, 2 * 4 + 0], [0.0, 0.25]),
             ([1 * 4 + 2], [0.75])]
    one_by_one, stacked = ContactFlags(fractions), ContactFlags(fractions)
    for links, at in steps:
        one_by_one.add(*_link_points(links, at))
    parts = [_link_points(links, at) for links, at in steps]
    flat = np.concatenate([p[0] for p in parts]).astype(np.int64)
    stacked.add_stacked(flat, *(np.concatenate([p[i] for p in parts]).reshape(-1, 3) for i in (1, 2, 3)),
                        np.array([len(links) for links, _ in steps]))
    (flags_a, poc_a), (flags_b, poc_b) = one_by_one.take(), stacked.take()
    assert np.array_equal(flags_a, flags_b) and np.array_equal(poc_a, poc_b, equal_nan=True)
    assert np.isfinite(poc_a).all()
