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
