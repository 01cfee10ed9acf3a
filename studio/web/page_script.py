"""Small fixes of the studio page, run in each tab once it connects (viser's
``RunJavascriptMessage``), for what viser 1.1's page lacks (issue 29, item 8):

* a text box's label names the box: viser's TextInput renders ``<label for=UUID>`` but its
  ``<input>`` has no id or Mantine's own (``mantine-xxxx``), so the label is not linked (a screen reader, a click on the label,
  Playwright's ``get_by_label`` do not find the box); the id is set here;
* PageUp / PageDown on a slider (the time slider) move it ten steps, as the WAI-ARIA slider
  pattern asks; Mantine's slider only knows the arrow keys and Home/End.
"""
from __future__ import annotations

PAGE_SCRIPT = r"""
(() => {
  if (window.__brushStudioPage) return;
  window.__brushStudioPage = true;
  const link = () => {
    document.querySelectorAll('label[for]').forEach(label => {
      const id = label.getAttribute('for');
      if (!id || document.getElementById(id)) return;
      let row = label.parentElement;
      for (let up = 0; row && up < 4; up++, row = row.parentElement) {
        const inputs = row.querySelectorAll('input:not([type=hidden]), textarea');
        if (inputs.length > 1) return;  // (past the label's own row)
        if (inputs.length === 1) {
          // Mantine gives a text box an id of its own, not the label's: point the label at it
          if (inputs[0].id) label.htmlFor = inputs[0].id; else inputs[0].id = id;
          return;
        }
      }
    });
  };
  new MutationObserver(link).observe(document.body, {childList: true, subtree: true});
  link();
  document.addEventListener('keydown', event => {
    if (event.key !== 'PageUp' && event.key !== 'PageDown') return;
    const thumb = event.target;
    if (!thumb || thumb.getAttribute('role') !== 'slider') return;
    event.preventDefault();
    const key = event.key === 'PageUp' ? 'ArrowRight' : 'ArrowLeft';
    // one arrow at a time, each after the slider took the last: ten dispatched at once all
    // read the same value, and the slider moved one step (seen in the browser test)
    const press = left => {
      if (left <= 0) return;
      const before = thumb.getAttribute('aria-valuenow');
      thumb.dispatchEvent(new KeyboardEvent('keydown', {key, code: key, bubbles: true}));
      let tries = 0;
      const wait = () => {
        if (thumb.getAttribute('aria-valuenow') !== before || ++tries > 20) press(left - 1);
        else setTimeout(wait, 15);
      };
      setTimeout(wait, 0);
    };
    press(10);
  }, true);
})();
"""


def send_page_script(target) -> None:
    """Run :data:`PAGE_SCRIPT` in the tab(s) of ``target`` (a viser ClientHandle)."""
    from viser import _messages

    try:
        target.gui._websock_interface.queue_message(
            _messages.RunJavascriptMessage(source=PAGE_SCRIPT))
    except Exception as exc:  # (viser internals changed: the page works without it)
        print(f"studio: page script not sent: {type(exc).__name__}: {exc}")
