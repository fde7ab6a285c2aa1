// assocbench report: sortable, filterable tables; inlined into every page (no network at view time).
// A header with class "sortable" sorts its table by the cells' data-v (numbers, or text where the
// column is text); a cell with no value sorts last in both directions. Each <select data-filter=KEY>
// keeps the rows whose data-KEY equals its value ("" = all).
(function () {
  function cellValue(row, index, numeric) {
    var v = row.cells[index].getAttribute("data-v");
    if (v === null || v === "") return null;
    return numeric ? parseFloat(v) : v;
  }
  function sortBy(th) {
    var table = th.closest("table"), body = table.tBodies[0];
    var index = Array.prototype.indexOf.call(th.parentNode.cells, th);
    var numeric = th.getAttribute("data-type") === "num";
    var ascending = th.getAttribute("aria-sort") !== "ascending";
    table.querySelectorAll("th[aria-sort]").forEach(function (h) { h.removeAttribute("aria-sort"); });
    th.setAttribute("aria-sort", ascending ? "ascending" : "descending");
    var rows = Array.prototype.slice.call(body.rows).map(function (r, k) { return [r, k]; });
    rows.sort(function (a, b) {
      var x = cellValue(a[0], index, numeric), y = cellValue(b[0], index, numeric);
      if (x === null || y === null) return (x === null) - (y === null) || a[1] - b[1];
      var c = numeric ? x - y : String(x).localeCompare(String(y));
      return (ascending ? c : -c) || a[1] - b[1];
    });
    rows.forEach(function (r) { body.appendChild(r[0]); });
  }
  function applyFilters() {
    var selects = document.querySelectorAll("select[data-filter]");
    document.querySelectorAll("table.filterable tbody tr").forEach(function (row) {
      var show = true;
      selects.forEach(function (s) {
        if (s.value !== "" && row.getAttribute("data-" + s.getAttribute("data-filter")) !== s.value) show = false;
      });
      row.hidden = !show;
    });
    document.querySelectorAll(".count").forEach(function (c) {
      var rows = document.querySelectorAll("table.filterable tbody tr");
      var shown = Array.prototype.filter.call(rows, function (r) { return !r.hidden; }).length;
      c.textContent = "showing " + shown + " of " + rows.length + " rows";
    });
  }
  document.addEventListener("DOMContentLoaded", function () {
    document.querySelectorAll("th.sortable").forEach(function (th) {
      th.addEventListener("click", function () { sortBy(th); });
    });
    document.querySelectorAll("select[data-filter]").forEach(function (s) { s.addEventListener("change", applyFilters); });
    var more = document.getElementById("more");
    if (more) more.addEventListener("change", function () { document.body.classList.toggle("show-more", more.checked); });
    applyFilters();
  });
})();
