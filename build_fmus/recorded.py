"""The source hash an FMU records (its model description's ``version``): what says whether it is stale.

Apart from the builder, so that a run whose FMUs are up to date reads their
hashes without importing the build machinery.
"""

import xml.etree.ElementTree as ET
import zipfile

__all__ = ["HASH_PREFIX", "recorded_hash"]

HASH_PREFIX = "dfwb-sources-"


def recorded_hash(fmu_path):
    """The source hash an existing FMU was built from, or None."""
    try:
        with zipfile.ZipFile(fmu_path) as archive:
            root = ET.fromstring(archive.read("modelDescription.xml"))
    except (OSError, KeyError, zipfile.BadZipFile, ET.ParseError):
        return None
    version = root.get("version", "")
    return version[len(HASH_PREFIX):] if version.startswith(HASH_PREFIX) else None
