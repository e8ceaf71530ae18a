"""The reference sim driver, noting when it sends each state (monotonic s, this machine's clock, which the
bridge's process shares): a stale-state event at the bridge can then be told apart from the driver itself
falling silent (a driver starved of CPU) and the bridge's process not reading what was sent.

    python -m bench.recording_driver SENT.npy [sim_driver options]
"""

from __future__ import annotations

import sys
import time

import numpy as np

from app.bridge import driver_client, sim_driver


def main(argv: list[str]) -> int:
    out, sent = argv[0], []
    send_state = driver_client.DriverClient.send_state

    def recording(self, *args, **kwargs) -> None:
        sent.append(time.monotonic())
        send_state(self, *args, **kwargs)

    driver_client.DriverClient.send_state = recording
    try:
        return sim_driver.main(argv[1:])
    finally:
        np.save(out, np.array(sent))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
