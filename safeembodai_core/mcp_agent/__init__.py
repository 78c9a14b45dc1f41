"""An agent that drives a served room through an MCP server, and the ablation that measures it under attack.

``safeembodai agent-ablate`` (docs/agent_ablation.md). The rooms, in the order a trial goes through them:

* :mod:`.cells` -- what a scenario's arms (ros-mcp direct, or through guard-mcp) and conditions (the
  instruction or what the camera reads, attacked) mean here;
* :mod:`.room` -- the trial's served room in a thread, with the text its camera reads;
* :mod:`.tools` -- the MCP server over stdio, with the official client: its tools, calls, results;
* :mod:`.loop` -- the agent's steps, until the room's outcome, the step budget or the clock;
* :mod:`.pilot` -- the scenario's backend (the mock pilot) as a tool-calling agent, with
  :mod:`.readings` (scan, frame, text off the read tools) and :mod:`.motions` (a plan as a
  ``publish_for_durations`` call, a refusal as data);
* :mod:`.tool_agent` -- a litellm model that calls the tools itself, its replies read by :mod:`.tool_reply`;
* :mod:`.deciders` -- which of the two a run uses;
* :mod:`.trial`, :mod:`.ablation` -- one trial judged by the room's record; every trial into a run folder.
"""
