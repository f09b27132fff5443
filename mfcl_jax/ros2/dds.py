"""One DDS participant speaking ROS 2's conventions: topic names, domain, QoS.

ROS 2 over DDS: the topic ``/scan`` is the DDS topic ``rt/scan``; the domain is
``ROS_DOMAIN_ID`` (0 when unset); the QoS profiles are the ones ROS 2 nodes use, so that
every reader here matches the usual writers and every writer matches the usual readers:

- ``SENSOR``: best effort, volatile, keep last N (``rclcpp::SensorDataQoS``, as LiDAR
  drivers publish). A best-effort reader also matches reliable writers, so odometry and
  ``/tf`` are read this way too.
- ``LATCHED``: reliable, transient local (``/tf_static``; ``/initialpose`` is written so, so
  that a reader started later, such as ``ros2 topic echo --qos-durability transient_local``,
  still gets the last pose; nav2's AMCL subscribes reliable and volatile, which matches).
- ``RELIABLE``: reliable, volatile, keep last 10 (``rclcpp::QoS(10)``, the default; the status).
- ``STREAM``: reliable, volatile, keep all: sensor streams that must arrive whole (``mfcl
  ros2 --reliable`` and ``mfcl play --reliable``: replays, tests). A reliable reader matches
  only reliable writers; over best effort, a loaded machine loses UDP samples.

The network interfaces and discovery peers are Cyclone DDS's own settings (``CYCLONEDDS_URI``),
as for a ROS 2 node running ``rmw_cyclonedds_cpp``.
"""

from __future__ import annotations

import os
import re

from mfcl_jax.io.errors import DataError

__all__ = ["Bus", "domain_id", "dds_topic", "take", "SENSOR", "LATCHED", "RELIABLE", "STREAM"]

_NAME = re.compile(r"^/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


def _qos():
    from cyclonedds.core import Policy
    from cyclonedds.qos import Qos
    from cyclonedds.util import duration

    sensor = Qos(Policy.Reliability.BestEffort, Policy.Durability.Volatile,
                 Policy.History.KeepLast(5000))  # fmt: skip
    latched = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)),
                  Policy.Durability.TransientLocal, Policy.History.KeepLast(100))  # fmt: skip
    reliable = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)),
                   Policy.Durability.Volatile, Policy.History.KeepLast(10))  # fmt: skip
    stream = Qos(Policy.Reliability.Reliable(duration(seconds=10)), Policy.Durability.Volatile,
                 Policy.History.KeepAll)  # fmt: skip
    return sensor, latched, reliable, stream


SENSOR, LATCHED, RELIABLE, STREAM = "sensor", "latched", "reliable", "stream"


def domain_id(env=None) -> int:
    """The DDS domain: ``ROS_DOMAIN_ID`` (0 when unset or empty).

    Raises:
        DataError: a value that is not an integer in 0..232.
    """
    text = (os.environ if env is None else env).get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return 0
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= 232:
        raise DataError(f"ROS_DOMAIN_ID: expected an integer in 0..232, got {text!r}")
    return value


def dds_topic(name: str) -> str:
    """ROS 2's DDS name of a topic: ``/scan`` -> ``rt/scan``.

    Raises:
        DataError: a name ROS 2 would refuse (empty, a part not starting with a letter, ...).
    """
    if not _NAME.match(name or ""):
        raise DataError(f"topic name {name!r}: expected e.g. /scan or /robot1/odom")
    return "rt/" + name.lstrip("/")


def take(reader) -> list:
    """The samples waiting in ``reader`` (its history emptied), without the invalid samples
    DDS hands out when a writer goes away."""
    out = []
    while True:
        got = reader.take(N=256)
        out += [s for s in got if s.sample_info.valid_data]
        if len(got) < 256:
            return out


class Bus:
    """A DDS participant on ``domain`` with ROS 2 topic readers and writers.

    Raises:
        DataError: DDS cannot start (the message of Cyclone DDS, e.g. a bad ``CYCLONEDDS_URI``).
    """

    def __init__(self, domain: int | None = None):
        from cyclonedds.core import DDSException
        from cyclonedds.domain import DomainParticipant

        self.domain = domain_id() if domain is None else int(domain)
        try:
            self.participant = DomainParticipant(self.domain)
        except DDSException as e:
            uri = os.environ.get("CYCLONEDDS_URI", "")
            where = f" (CYCLONEDDS_URI={uri!r})" if uri else ""
            raise DataError(f"DDS domain {self.domain}: cannot start{where}: {e}") from None
        self._qos = dict(zip((SENSOR, LATCHED, RELIABLE, STREAM), _qos(), strict=True))
        self._topics: dict = {}

    def _topic(self, name: str, kind):
        from cyclonedds.topic import Topic

        key = dds_topic(name)
        if key not in self._topics:
            self._topics[key] = Topic(self.participant, key, kind)
        return self._topics[key]

    def waiter(self, readers):
        """``wait(seconds)``: returns once one of ``readers`` (None entries skipped) holds a
        sample, or after ``seconds``."""
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState, WaitSet
        from cyclonedds.util import duration

        ws = WaitSet(self.participant)
        mask = SampleState.NotRead | ViewState.Any | InstanceState.Any
        conditions = [ReadCondition(r, mask) for r in readers if r is not None]
        for c in conditions:
            ws.attach(c)

        def wait(seconds: float) -> None:
            ws.wait(duration(seconds=seconds))

        wait.conditions = conditions  # kept alive with the function
        return wait

    def reader(self, name: str, kind, qos: str = SENSOR):
        from cyclonedds.sub import DataReader

        return DataReader(self.participant, self._topic(name, kind), qos=self._qos[qos])

    def writer(self, name: str, kind, qos: str = RELIABLE):
        from cyclonedds.pub import DataWriter

        return DataWriter(self.participant, self._topic(name, kind), qos=self._qos[qos])
