"""The hardware bridge: a FastAPI server a real robot's driver connects to, and the operator's HTTP API.

- `server.BridgeServer`: uvicorn in a background thread (127.0.0.1 unless configured otherwise);
- `bridge_robot.BridgeRobot`: the `RobotBackend` the runtime drives, fed by the robot link;
- `robot_socket`: the `/robot` WebSocket (state and depth frames in, velocity commands out);
- `routes/`: the operator API (health, state, plan, progress, sequence, run control, scene);
- `sim_driver`: a reference driver running the MuJoCo robot in its own process (`python -m app.bridge.sim_driver`).

The protocol for writing a driver is in `docs/bridge.md`. This package never imports `app.ui`.
"""
