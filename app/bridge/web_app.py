"""The bridge's FastAPI application: the robot link, the operator API and its OpenAPI schema."""

from __future__ import annotations

from fastapi import FastAPI

from app.bridge.auth import Token
from app.bridge.bridge_robot import BridgeRobot
from app.bridge.errors import install_error_handlers
from app.bridge.protocol import PROTOCOL_VERSION, ErrorOut
from app.bridge.robot_link import RobotLink
from app.bridge.robot_socket import router as robot_router
from app.bridge.routes import objects, run, scene, sequence, status

DESCRIPTION = """Hardware bridge of Perceptive HTMPC Studio.

A robot driver connects to the `/robot` WebSocket (protocol: `docs/bridge.md`); an operator drives
the runtime through `/api`. Every request that changes anything needs `Authorization: Bearer <token>`.
"""


def create_app(token: Token, link: RobotLink, robot: BridgeRobot) -> FastAPI:
    """The application; `app.state` holds the token, the link, the robot and the runtime attachment."""
    app = FastAPI(title="HTMPC hardware bridge", version=f"{PROTOCOL_VERSION}.0", description=DESCRIPTION,
                  responses={500: {"model": ErrorOut, "description": "Internal error (logged by the studio)"}})
    app.state.token, app.state.link, app.state.robot = token, link, robot
    app.state.attachment = None
    install_error_handlers(app)
    for router in (status.router, run.router, sequence.router, scene.router, objects.router, robot_router):
        app.include_router(router)
    return app
