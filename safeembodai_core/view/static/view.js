// The run page's trial filter: rows whose text holds every word typed stay shown. Reads only the
// page's own table; never fetches anything.
"use strict";
document.addEventListener("DOMContentLoaded", function () {
  var input = document.getElementById("filter");
  var table = document.getElementById("trials");
  var shown = document.getElementById("shown");
  if (!input || !table) { return; }
  var rows = Array.prototype.slice.call(table.tBodies[0].rows);
  function apply() {
    var words = input.value.toLowerCase().split(/\s+/).filter(Boolean);
    var count = 0;
    rows.forEach(function (row) {
      var text = row.textContent.toLowerCase();
      var keep = words.every(function (word) { return text.indexOf(word) >= 0; });
      row.classList.toggle("hidden", !keep);
      if (keep) { count += 1; }
    });
    shown.textContent = count + " of " + rows.length + " trials";
  }
  input.addEventListener("input", apply);
  apply();
});
