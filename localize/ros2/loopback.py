"""A DDS environment confined to this machine's loopback interface (tests, benchmarks, trying
the node and the player on one machine).

``loopback_env(folder)`` writes a Fast DDS profile whose only transport is UDPv4 on
127.0.0.1 (no shared memory, no other interface) and returns the environment that selects it
with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a random ``ROS_DOMAIN_ID``; set it before
``rclpy.init`` (``os.environ.update``) or pass it to a subprocess.
"""

from __future__ import annotations

import random
from pathlib import Path

from core.atomic import atomic_write_text

PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<dds xmlns="http://www.eprosima.com">
  <profiles>
    <transport_descriptors>
      <transport_descriptor>
        <transport_id>loopback_udp</transport_id>
        <type>UDPv4</type>
        <interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>
      </transport_descriptor>
    </transport_descriptors>
    <participant profile_name="loopback" is_default_profile="true">
      <rtps>
        <userTransports><transport_id>loopback_udp</transport_id></userTransports>
        <useBuiltinTransports>false</useBuiltinTransports>
      </rtps>
    </participant>
  </profiles>
</dds>
"""


def loopback_env(folder: str | Path, domain_id: int | None = None) -> dict[str, str]:
    """Write ``folder/fastdds_loopback.xml`` and return the variables that confine DDS to
    loopback: the profile, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, Fast DDS as the RMW
    and ``ROS_DOMAIN_ID`` (``domain_id``, or random in 1..100 so parallel runs do not meet)."""
    path = Path(folder) / "fastdds_loopback.xml"
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, PROFILE)
    domain = random.randint(1, 100) if domain_id is None else int(domain_id)
    return {"FASTDDS_DEFAULT_PROFILES_FILE": str(path),
            "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
            "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp", "ROS_DOMAIN_ID": str(domain)}
