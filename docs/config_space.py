"""Draw the permissible configuration space of the OCP paper's four-wheel example vehicle.

Four steered wheels at (±a/2, ±b/2) with a = 0.43 m, b = 0.23 m, steering limit ±155°, rim-speed limit
1 m/s (omni-curve-parameters.md §4.1-4.3, Figs. 9 and 12). Colour is v_max(κ_n, β); black is the blocked
region, where a steering angle would leave its range; white crosses mark the singular points where the
ICR lies on a wheel. Run `python docs/config_space.py` to rewrite docs/config_space.png.
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sim.kinematics.chassis_presets import steered4  # noqa: E402
from sim.kinematics.ocp import configuration_space, kappa_g_for, ocp_grid  # noqa: E402


def main() -> Path:
    """Sample the (κ_n, β) plane, plot v_max with the blocked region, and save the PNG next to this file."""
    chassis = steered4(wheelbase=0.43, track=0.23, steer_limit=np.radians(155), max_speed=1.0)
    kappa_n, beta = ocp_grid(321, 721)
    space = configuration_space(chassis, kappa_n, beta)
    v_max = np.ma.masked_where(space.blocked, space.v_max)

    fig, ax = plt.subplots(figsize=(8, 5), dpi=110)
    cmap = plt.get_cmap("viridis").copy()
    cmap.set_bad("black")
    mesh = ax.pcolormesh(np.degrees(beta), kappa_n, v_max, cmap=cmap, vmin=0, vmax=1, shading="nearest")
    fig.colorbar(mesh, ax=ax, label="v_max [m/s] (black: blocked)")
    tip = 90 - np.degrees(np.arctan2(0.23, 0.43))  # 61.858°: the ICR reaches a wheel at |κ_n| = 1
    singular = np.array([(b, k) for k in (1, -1) for b in (tip, -tip, 180 - tip, tip - 180)])
    ax.plot(singular[:, 0], singular[:, 1], "w+", markersize=9, label="ICR on a wheel (singular)")
    ax.set_xlabel("float angle β [deg]")
    ax.set_ylabel("nominal curvature κ_n [–]")
    ax.set_xticks(np.arange(-180, 181, 45))
    ax.set_yticks(np.arange(-2, 2.01, 0.5))
    ax.set_title("Permissible configuration space: 4 steered wheels, a = 0.43 m, b = 0.23 m,\n"
                 f"steering limit ±155°, u_lim = 1 m/s, κ_g = {kappa_g_for(chassis):.3f} 1/m "
                 f"(blocked: {100 * space.blocked.mean():.1f} %)", fontsize=10)
    ax.legend(loc="lower right", fontsize=8, facecolor="0.3", labelcolor="white", framealpha=0.8)
    fig.tight_layout()
    out = Path(__file__).with_suffix(".png")
    fig.savefig(out)
    plt.close(fig)
    return out


if __name__ == "__main__":
    print(main())
