"""Fig. 3-style figures: broken lines at the angle wrap, a legend clear of the traces, the
rewards of both agents told apart."""
import matplotlib.pyplot as plt
import numpy as np

from twolink.policy.fuzzy_policy import load_policy
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout
from twolink.viz.plots import broken_at_wraps, fig3_figure


def test_a_wrapped_angle_breaks_its_line_between_the_two_samples():
    t = np.array([0.0, 0.05, 0.10, 0.15])
    theta = np.array([3.0, 3.12, -3.13, -3.0])        # crosses +pi between t=0.05 and 0.10
    tt, th = broken_at_wraps(t, theta)
    assert np.allclose(tt, [0.0, 0.05, 0.075, 0.10, 0.15])
    assert np.isnan(th[2]) and th[[0, 1, 3, 4]].tolist() == theta.tolist()
    same_t, same = broken_at_wraps(t, np.array([0.1, -0.1, 0.2, 3.0]))   # no jump over pi
    assert len(same_t) == 4 and not np.isnan(same).any()


def _runs(x0):
    plant = make_plant("simplified")
    return {name: rollout(load_policy(name), plant, x0, duration=1.0)
            for name in ("centralized", "decentralized")}


def test_the_legend_sits_below_the_panels_and_names_each_reward():
    runs = _runs(np.array([-1.0, -3.0, 0.0, 0.0]))          # link 2 wraps past -pi
    fig = fig3_figure({"(a)": {"simplified": runs["centralized"]},
                       "(b)": {"simplified": runs["decentralized"]}})
    try:
        fig.canvas.draw()
        (legend,) = fig.legends
        labels = [t.get_text() for t in legend.get_texts()]
        assert labels[:2] == ["link 1", "link 2"]
        assert "reward (15)" in labels and "reward (17) of agent i in link i's colour" in labels
        assert "angle wraps at +-pi (line broken)" in labels
        # No axes carries a legend of its own, and the figure's legend is under every panel.
        assert all(a.get_legend() is None for a in fig.axes)
        box = legend.get_window_extent()
        assert all(box.y1 <= a.get_window_extent().y0 for a in fig.axes)
        # The decentralized column draws both agents' rewards, link 1's line the wider.
        r1, r2 = fig.axes[7].get_lines()[:2]
        assert r1.get_color() != r2.get_color() and r1.get_linewidth() > r2.get_linewidth()
    finally:
        plt.close(fig)
