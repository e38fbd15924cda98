"""
Bounded DDS memory for every node: a Fast DDS profile whose history payloads are freed.

rmw_fastrtps keeps each reader's payload buffers at the size of the largest message it ever
got (one 4000x4000 image: 46 MB for the node's life). ``use_freed_payloads`` points Fast DDS at
``data/fastdds_profile.xml`` (DYNAMIC history memory) before ``rclpy.init``, unless the user
configures Fast DDS with XML of their own; ``RMW_FASTRTPS_USE_QOS_FROM_XML=0`` switches it off.
"""

import os
from pathlib import Path
from typing import MutableMapping

PROFILE = Path(__file__).resolve().parent / 'data' / 'fastdds_profile.xml'
USER_SETTINGS = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE',
                 'RMW_FASTRTPS_USE_QOS_FROM_XML')


def use_freed_payloads(environ: MutableMapping[str, str] = os.environ) -> bool:
    """Select the profile in ``environ`` (this process's); False if the user chose their own."""
    if any(name in environ for name in USER_SETTINGS) or not PROFILE.exists():
        return False
    environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(PROFILE)
    environ['RMW_FASTRTPS_USE_QOS_FROM_XML'] = '1'  # take the memory policy from the profile
    return True
