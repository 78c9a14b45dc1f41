"""``safeembodai guard-mcp``: the guard in front of a robot's MCP server (ros-mcp 3.x by default).

An MCP server that lists the upstream's tools verbatim and answers each call under a policy
(docs/guard_mcp.md). The rooms, in the order a call goes through them:

* :mod:`.policy` -- the policy file: which tool is what, velocity topics, allowlists, thresholds;
* :mod:`.calls` -- the agent's arguments read strictly: a :class:`~.calls.Motion`, a forward, or a refusal;
* :mod:`.senses` -- the robot's own scan and odometry, read over rosbridge by guard-mcp itself;
* :mod:`.judging` -- the motion judged by the Guard on that scan, with the advice to amend it;
* :mod:`.slices` -- a motion run through the upstream in slices, each re-judged on the newest scan;
* :mod:`.proxy` -- one call from arguments to result: the verdict, refusals in a row, the call's record
  (:mod:`.records`);
* :mod:`.agent` -- what the agent is told: the security prefix, results marked untrusted, R_{i-1};
* :mod:`.session` -- every call as a step of a run folder that ``show`` and ``view`` read;
* :mod:`.upstream`, :mod:`.server` -- the upstream as an MCP client, guard-mcp as an MCP server.
"""
