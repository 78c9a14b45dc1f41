"""Where bytes from outside enter, and the one reader each goes through: the inventory.

Every entry point below names the strict reader its bytes must pass before anything else reads them.
``tests/core/trust/test_inventory.py`` reads the source of the core and the built-in plugins and
fails when a module calls a raw reader (``open``, ``read_text``, ``read_bytes``, ``json.loads``,
``model_validate_json``, ``sqlite3.connect``, ``yaml.safe_load``, ``os.open``) without being listed in
:data:`RAW_READERS` with the reason it may: a new way in is added here, with its reader, or it fails.
Each reader named here must exist (the test imports it). ``docs/trust.md`` is the same list for people.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class EntryPoint:
    """Bytes from outside: what they are, and ``module:function`` of the one reader they go through."""

    name: str
    what: str
    reader: str
    #: the optional extra whose package the reader's module imports (``pip install -e ".[EXTRA]"``); None: the
    #: README's install holds it
    extra: str | None = None


ENTRY_POINTS: tuple[EntryPoint, ...] = (
    EntryPoint("llm reply", "a backend's reply, live, replayed from a run or read back from the response cache",
               "safeembodai_core.models.reply:read_reply"),
    EntryPoint("llm envelope", "a chat-completion server's raw body (choices, finish reason, envelope keys)",
               "safeembodai_core.models.strict_json:read_json_document"),
    EntryPoint("server usage", "a server's token counts, raw or as litellm parsed them",
               "safeembodai_core.models.chat_completion:read_usage"),
    EntryPoint("cached reply", "a reply file of the response cache (responses/, --cache DIR)",
               "safeembodai_core.loop.response_cache:stored_reply"),
    EntryPoint("run folder file", "scenario.json, finished.jsonl, response_cache.json, bags/storage",
               "safeembodai_core.runs.files:read_run_text"),
    EntryPoint("run folder picture", "a picture or figure of a run folder shown by view",
               "safeembodai_core.runs.files:read_regular_file"),
    EntryPoint("results store", "the sqlite store's rows (a result, a step record), every query bounded",
               "safeembodai_plugins.state.sqlite_db:SqliteStateStore._row"),
    EntryPoint("scenario file", "a scenario YAML given on the command line or read by a task",
               "safeembodai_core.scenario.limits:read_scenario_text"),
    EntryPoint("bag plan", "a JSON plan message of a recorded bag (guard-bag)",
               "safeembodai_core.models.strict_json:read_json_document"),
    EntryPoint("robot file", "a robot YAML given to guard-node --robot or guard-mcp --robot (body, scanners, limits)",
               "safeembodai_core.ros.robot_file:read_robot_file"),
    EntryPoint("guard-mcp policy", "the policy YAML given to guard-mcp --policy (tools, velocity topics, allowlists)",
               "safeembodai_core.guard_mcp.policy:read_policy"),
    EntryPoint("mcp tool call", "the arguments of a tools/call an agent sends guard-mcp, before anything is forwarded",
               "safeembodai_core.guard_mcp.calls:read_call"),
    EntryPoint("mcp tool result", "what the upstream MCP server answers a call guard-mcp forwards (a topic's text, a "
               "camera's image, anything the robot's side wrote), on its way to the agent: marked as untrusted data",
               "safeembodai_core.guard_mcp.agent:mark_untrusted", extra="mcp"),
    EntryPoint("rosbridge frame", "a WebSocket text frame a rosbridge client sends the server, or a server sends the "
               "client (serve-robot, guard-node)", "safeembodai_core.rosbridge.frames:read_frame"),
    EntryPoint("ray worker event", "what a Ray worker on another machine sends for its trial",
               "safeembodai_core.ablation.relay:RelayedWrites.receive"),
    EntryPoint("inspect model output", "what Inspect's model hands the solver (only on a provider that shows the "
               "whole reply: safeembodai/<backend> or mockllm)",
               "safeembodai_core.integrations.inspect.bridge:backend_reply", extra="inspect"),
    EntryPoint("inspect usage", "the token counts of Inspect's model output",
               "safeembodai_core.integrations.inspect.bridge:output_usage", extra="inspect"),
    EntryPoint("inspect provider", "the model Inspect was told to use: a provider that parses the body itself is "
               "refused", "safeembodai_core.integrations.inspect.providers:check_provider", extra="inspect"),
    EntryPoint("view request", "an HTTP request to `view --serve` (request line and headers read by http.server, "
               "the target by _asked_path): the one file of the site it is answered with",
               "safeembodai_core.view.serve:open_site_file"),
    EntryPoint("guard events", "what a CommandFilter is given, in any order: scans, poses, velocity commands and "
               "their times (guard-node's subscriptions, a bag, a caller's)",
               "safeembodai_core.guard.command_filter:CommandFilter.on_command"),
)

#: Modules that call a raw reader, and why they may. Everything else goes through an entry point's reader.
RAW_READERS: dict[str, str] = {
    "safeembodai_core.runs.files": "the bounded reader itself (regular files, no symlink, no FIFO, size-capped)",
    "safeembodai_core.scenario.limits": "the scenario file's bounded reader itself",
    "safeembodai_core.loop.response_cache": "decodes what the bounded reader returned; writes its own index",
    "safeembodai_core.runs.folder": "decodes the bounded reader's text; its own lock files and /proc/locks",
    "safeembodai_plugins.state.sqlite_db": "the store's own SQLite file, read row by row through _row",
    "safeembodai_core.cli.guard_bag_cmd": "a bag's messages, through rosbags' reader, then read_json_document",
    "safeembodai_core.rosbridge.frames": "the rosbridge frame reader itself (size, depth, duplicate keys, numbers)",
    "safeembodai_core.guard.bag_guard": "rosbags' reader of a bag (the library parses the container)",
    "safeembodai_core.mcp_agent.tools": "appends an MCP server's stderr to the trial's own log (no read)",
    "safeembodai_core.mcp_agent.trial": "the shipped default guard-mcp policy (package data), merged with the arm's "
                                        "keys",
    "safeembodai_core.serve_robot.session_bag": "writes the session's own bag; export reads a session's bag back "
                                                "through rosbags' reader (the library parses the container)",
    "safeembodai_core.runs.trial_files": "a bag this process has just written in a scratch folder of its own",
    "safeembodai_core.runs.rerun_recording": "a recording this process has just written in a scratch folder of its own",
    "safeembodai_core.report.paper": "the paper's values shipped in the package (safeembodai_core/data)",
    "safeembodai_core.report.writer": "writes metrics.csv (no read)",
    "safeembodai_core.cli.trial_view": "writes steps.jsonl (no read)",
    "safeembodai_core.view.site": "the site's own manifest and static files shipped in the package",
    "safeembodai_core.view.runs": "probes the run's lock without reading it",
    "safeembodai_core.view.files": "writes the site's files (no read)",
    "safeembodai_core.view.serve": "sends, unread, the site's file run_files.open_inside opened (a regular file "
                                   "reached with no symlink)",
    "safeembodai_core.ablation.warm_start": "the scenario as this process serialised it for its fork server",
    "safeembodai_core.ablation.runner_pool": "duplicates this process's stderr (no read)",
    "safeembodai_core.ablation.relay": "names its own outboxes open (no read)",
    "safeembodai_core.integrations.inspect.bridge": "a finish reason safeembodai/<backend> itself quoted as a JSON "
                                                    "string (quote_untrusted), read back as text only",
    "safeembodai_plugins.backends.litellm.errors": "an error body the strict reader refused, read for its message",
    "safeembodai_plugins.backends.litellm.local_server": "the local model server this process started, and its log",
    "safeembodai_plugins.backends.mock.reading": "the simulated pilot reading its own prompt's JSON",
    "safeembodai_plugins.environments.pybullet_rooms.movers": "the room's own world report, from its ground truth",
    "safeembodai_plugins.environments.pybullet_rooms.quiet": "opens /dev/null to silence pybullet (no read)",
}
