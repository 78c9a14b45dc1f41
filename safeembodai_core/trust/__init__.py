"""The trust boundary: where bytes from outside enter, and what a person is shown of them.

``inventory`` lists every entry point and the one strict reader each goes through (a test keeps it
true); ``text`` holds the one control-character pattern and the escapers for a terminal, a log and a
store; ``quoting`` quotes untrusted text before an LLM or a person reads it again; ``redaction``
masks credentials; ``world_private`` declares what only the simulator knows, so no defence reads it.
"""
