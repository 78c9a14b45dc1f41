"""Built-in Jinja templates of the secure prompt (imported as ``safeembodai_prompts``).

``system.j2`` renders Table I of the paper (role r, task t, capabilities b, response format f,
methods m) and, when secure prompting is on, the security prefix p from ``security/<variant>.j2``
(``paper``, ``hierarchy``, ``spotlight``, ``sandwich``). ``user.j2`` renders the user prompt I_i
(human instruction, text modalities, reference state R_{i-1}, previous failures on a retry).
Copy any of them into a folder and point the ``jinja`` prompt builder's ``template_dir`` at it to
change them; see ``docs/defences.md``.
"""

from pathlib import Path

TEMPLATE_DIR = Path(__file__).resolve().parent
