"""The public Crazyflie data set's files: where each one lives in its origin repository
and its SHA-256, so that ``python -m pinquad.data fetch crazyflie`` downloads exactly the
files the README's tables were computed from (pinquad.io.datafetch).

The files are the IMRC Lab's (TU Berlin) public repository ``crazyflie-data-collection``
at one pinned commit; the repository carries no licence file, so pinquad never ships or
copies them: each user downloads them from their origin into a cache directory.

How far the origin paths were checked (docs/data.md): the commit is the one named in the
data set's provenance note (``4d777a5a``), its full hash found in a public index of the
repository; the files marked ``verified`` were matched there by content and size; the
others' paths are the provenance note's folders (the binary flight logs are not in that
index) and could not be checked from a machine without access to GitHub. A wrong path
fails the download loudly (HTTP 404) and a wrong file fails its SHA-256: it can never
give silently different data. ``--base-url`` / ``--mirror`` point the fetch elsewhere.
"""

from __future__ import annotations

from dataclasses import dataclass

REPOSITORY = "IMRCLab/crazyflie-data-collection"
"""The origin repository (GitHub owner/name)."""
COMMIT = "4d777a5aef86ec45fb957f70dddb5b7fec2dfbe5"
"""The pinned commit every origin path below is read at."""
ORIGIN_BASE_URL = f"https://raw.githubusercontent.com/{REPOSITORY}/{COMMIT}/"
"""Raw-file URL prefix of the origin at ``COMMIT``; ``ORIGIN_BASE_URL + upstream`` is a file."""


@dataclass(frozen=True)
class CrazyflieFile:
    """One file of the data set.

    name: its path in the local data directory (``imrc_brushed/jana00``), the layout
        every real-data command reads (``--data DIR`` / ``$PINQUAD_CRAZYFLIE_DATA``).
    upstream: its path in ``REPOSITORY`` at ``COMMIT``.
    sha256: hex SHA-256 of its bytes.
    size: its length [bytes].
    verified: True when ``upstream`` was matched by content in the public index of the
        repository; False when it follows the provenance note's folder only.
    """

    name: str
    upstream: str
    sha256: str
    size: int
    verified: bool


CRAZYFLIE_FILES: tuple[CrazyflieFile, ...] = (
    CrazyflieFile(
        "brushless_calibration/data_calib_brushless.csv",
        "brushless_prototype_calibration/data/data_calib_brushless.csv",
        "dab3feb0827f1049c9682039f71263bd3208ef5d788bc9f0f7220701db927fd5", 302571, verified=True),
    CrazyflieFile(
        "brushless_calibration/manual_data_calib_brushless.csv",
        "brushless_prototype_calibration/data/manual_data_calib_brushless.csv",
        "1a3133c496fb0bbb10a8171fccc3386f1ff846e1aa836373819662a07b99624c", 155, verified=True),
    CrazyflieFile(
        "imrc_brushed/jana00",
        "brushed_flights/data/jana00",
        "924066914dffe93b8d272c91afab58be7e29f53579bde608e67296440389854a", 456351, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana01",
        "brushed_flights/data/jana01",
        "87425400f56b11b321fdc581ffe0dd63bf613caab134e1bd8948a8c566648a5d", 2555623, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana02",
        "brushed_flights/data/jana02",
        "d532e53ea533799b60b021cae56fdbfc6c10e51f0cdc748404503d7430ad06c9", 383279, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana03",
        "brushed_flights/data/jana03",
        "e10743d31b7e9a5126dd57674a6b57d6ccaf27e0be79b9610030beb7269cba49", 384449, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana04",
        "brushed_flights/data/jana04",
        "45888ce8b422353980f11a666b65580209a565b2f2f2f0be6c4fbdc94d10d243", 2555165, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana05",
        "brushed_flights/data/jana05",
        "254587a0ef24c7fcf7a5caa8fa49e44ccbae9e278bd5f6b06b235a5db62d7479", 2061363, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana10",
        "brushed_flights/data/jana10",
        "9a52021dd7fb450dd2684b820610f2136808b7831d77693ff9355020f1780f07", 589235, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana20",
        "brushed_flights/data/jana20",
        "a12ed8fef934751690f2fb2bdcf0bbdc585dc9a89283d86225a6a21a6ec24b09", 772561, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana23",
        "brushed_flights/data/jana23",
        "02c5399d09855353bedf9ba194aaffc090b230ba47a910202fae06ce6c153e61", 723529, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana24",
        "brushed_flights/data/jana24",
        "bbac5ecfd3540ee0210a5a5e74f22f2cf80f4197256ce37397e1d32b84d6984a", 720867, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana25",
        "brushed_flights/data/jana25",
        "de4ce2e30e5a8e7635c5ec820341c7868afe3eeedcc84abe0cc3c1ecff580013", 665705, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana27",
        "brushed_flights/data/jana27",
        "3947b89737a69bd5b2d2607bb124ba54f04777cf8138d3f7209430acde6a9631", 653133, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana28",
        "brushed_flights/data/jana28",
        "2a8c2c0d1710e50af3fb32700ee347a515e4d033bc1b350517324c0a03ce169b", 663735, verified=False),
    CrazyflieFile(
        "imrc_brushed/jana29",
        "brushed_flights/data/jana29",
        "e1b2a64b9482dcac2d5be1872b578a951705cc407b69377e4570e2510eba4803", 628473, verified=False),
    CrazyflieFile(
        "imrc_brushless/eckart00",
        "brushless_flights/data/eckart00",
        "b5bc9c6df9c97bda77912c0ccdb947447787ab46c014455e37ab8df3b692f819", 462007, verified=False),
    CrazyflieFile(
        "imrc_brushless/eckart01",
        "brushless_flights/data/eckart01",
        "fb294d513f0677c81247ddb28596312755619ea16f7aafe8fa9cb5e7c86d2acb", 462191, verified=False),
    CrazyflieFile(
        "imrc_brushless/eckart02",
        "brushless_flights/data/eckart02",
        "8a5da60763dcf5fc120d107bbd61b729db09495359661575632d3d9a84f947f7", 462245, verified=False),
    CrazyflieFile(
        "imrc_brushless/eckart03",
        "brushless_flights/data/eckart03",
        "5eb5ed1f68c24dda6095cf43dc02a79b410d34d14a8b1b83011332f8745f5c9b", 461731, verified=False),
    CrazyflieFile(
        "imrc_brushless/eckart04",
        "brushless_flights/data/eckart04",
        "223b965250b6495ae34b0ea5b0a9b34a627439de5c5c5d3c78f91a63cfc5419f", 462229, verified=False),
    CrazyflieFile(
        "imrc_brushless/eckart06",
        "brushless_flights/data/eckart06",
        "4e3036370adad8914f48debefeadced6325d03695ba120d239e580a4542b1beb", 425101, verified=False),
    CrazyflieFile(
        "imrc_brushless/eckart07",
        "brushless_flights/data/eckart07",
        "aa81809979be3ee90a4434bf97cfab16548d3ab0e49a4a9f7d745847ba8878da", 426021, verified=False),
    CrazyflieFile(
        "imrc_brushless/eckart08",
        "brushless_flights/data/eckart08",
        "4015d33fd8eaf0ad4261c22ebcb4d9e0a954cf92add3052d0ac44c5b6c4e8d6e", 425745, verified=False),
    CrazyflieFile(
        "imrc_brushless/eckart09",
        "brushless_flights/data/eckart09",
        "64c261507f716d6930a1eaf61c62aaa53c9640c3de07b36e51ea4f242a68c2cf", 425907, verified=False),
    CrazyflieFile(
        "imrc_brushless/eckart11",
        "brushless_flights/data/eckart11",
        "6241ec9931229359a5fd770b6ade1f7ce45f67640a586f0b50bd5b23c510f997", 419483, verified=False),
    CrazyflieFile(
        "imrc_brushless/usd_config.txt",
        "brushless_prototype_flights/config.txt",
        "889767947accbe5b1baf4d1e4f769d8a2a457bcc8f2d910b5813ca7ba0fce259", 572, verified=True),
    CrazyflieFile(
        "thrust_stand/cf2.1-stock-prop.csv",
        "system-id/data/cf21_bitcraze2021/cf2.1-stock-prop.csv",
        "c5a9ad8f22d6a2b6211fd16e76ecabd7512c8ccc49993b95f5fad58f72976316", 180892, verified=False),
    CrazyflieFile(
        "thrust_stand/cf21_stock2.csv",
        "system-id/data/cf21_bitcraze2021/cf21_stock2.csv",
        "853a755c008f9c2dc72a86dbe7a01c1a6917565cba27ab2a6ece0934d812aa70", 122305, verified=False),
)
"""Every file the real-data commands read: the 14 brushed flights (``realdata``,
``realdiscovery``, ``response``, ``axis_inertia``), the two thrust-stand runs
(``actuators``, kf of every real-data command), the brushless vehicle's 10 flights, its
logging configuration and its two calibration files (``--vehicle`` work)."""
