"""``gpt-4o`` and ``local``: LLM backends through litellm (work in progress, issue 4)."""
