"""A node busy with back-to-back ticks still reads every datagram waiting on its socket.

asyncio's datagram transport reads one datagram per event-loop iteration. A node behind its rate (physics
catching up, one iteration between ticks) then read about one control message per tick while dozens arrived
each second: its receive queue grew to 900 KB and a panel's messages acted 20 s late."""

from __future__ import annotations

import asyncio
import socket

from common.messages import Hello, OscMessage
from common.messages.codec import encode
from common.transport import UdpEndpoint


def test_every_datagram_waiting_is_read_within_a_few_loop_iterations() -> None:
    async def main() -> int:
        endpoint = await UdpEndpoint.open("127.0.0.1", 0)
        got: list[OscMessage] = []
        endpoint.set_handler(lambda message, source: got.append(message))
        packet = encode(Hello(role="panel", node_id="p", protocol=1, osc_port=9))
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            for _ in range(50):  # they arrive while the loop is busy (this coroutine does not yield)
                sender.sendto(packet, ("127.0.0.1", endpoint.port))
        for _ in range(3):  # three loop iterations, as three back-to-back ticks leave
            await asyncio.sleep(0)
        endpoint.close()
        return len(got)

    assert asyncio.run(main()) == 50
