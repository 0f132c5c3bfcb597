"""An independent ROS 2 peer for tests/ros2_interop.rs: Eclipse Cyclone DDS
(its Python binding) with the ROS 2 type names and the `rt/` prefix. It
says "chair" on /opennav/prompt until the chair answers, then listens to
/opennav/said and /opennav/state until "Arrived at the chair." or the time
limit; prints one JSON object: what it heard."""
import json
import sys
import time
from dataclasses import dataclass

from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic


@dataclass
class String_(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str


limit = float(sys.argv[1]) if len(sys.argv) > 1 else 60.0
dp = DomainParticipant(0)
prompt = DataWriter(dp, Topic(dp, "rt/opennav/prompt", String_))
said = DataReader(dp, Topic(dp, "rt/opennav/said", String_))
state = DataReader(dp, Topic(dp, "rt/opennav/state", String_))
heard, states = [], []
end = time.time() + limit
last_prompt = 0.0
while time.time() < end:
    heard += [s.data for s in said.take(N=50)]
    states += [json.loads(s.data) for s in state.take(N=50)]
    going = heard or any(s.get("goal") == "chair" for s in states)
    if not going and time.time() - last_prompt > 0.5:
        prompt.write(String_(data="chair"))
        last_prompt = time.time()
    if "Arrived at the chair." in heard:
        break
    time.sleep(0.05)
print(json.dumps({"heard": heard, "states": states[-3:], "n_states": len(states)}))
