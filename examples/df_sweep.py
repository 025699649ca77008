"""A describing-function sweep of the friction plant, with its Nyquist plot of -1/N.

Run it as ``python examples/df_sweep.py [OUT_DIR]``: it prints a few points,
writes ``friction_nyquist.png`` and a resumable sweep (``sweep/results.csv``
and ``sweep/results.json``) into OUT_DIR (default: the current folder).
Only the public API is used: ``import dfwb``.
"""

import sys
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import dfwb


def main(out_dir="."):
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)

    # N(F, omega) on a broadcast grid: 3 forces (a column) x 25 frequencies (a row).
    F = np.array([[10.0], [20.0], [50.0]])  # [N]
    omega = np.geomspace(0.1, 10.0, 25)  # [rad/s]
    response = dfwb.describing_function("friction", F, omega)
    print(f"N has shape {response.N.shape}; all periodic: {bool(response.periodic.all())}")
    for record in response.points[:3]:
        print(f"  F = {record['F']:g} N, omega = {record['omega']:.3g} rad/s: "
              f"N = {record['N_re']:.6g} {record['N_im']:+.6g}j m/N")

    # The Nyquist plot of -1/N, one curve per force.
    figure, ax = plt.subplots(figsize=(6, 4.5))
    response.plot(ax=ax)
    ax.legend(fontsize=8)
    ax.set_title("friction: -1/N(F, omega), omega from 0.1 to 10 rad/s")
    figure.savefig(out_dir / "friction_nyquist.png", dpi=100)
    plt.close(figure)

    # The same points as a resumable sweep on disk (results.csv: one record per row, units in the header).
    records = dfwb.sweep("friction", dfwb.grid([10.0, 20.0, 50.0], omega.tolist()), out_dir / "sweep", jobs=1)
    assert [r["N_re"] for r in records] == response.N.real.ravel().tolist()  # the same numbers, to the bit
    print(f"{len(records)} points in {out_dir / 'sweep' / 'results.csv'}")
    return response


if __name__ == "__main__":
    main(*sys.argv[1:2])
