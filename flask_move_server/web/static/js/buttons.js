// A list row's button, greyed as the page's rules say: "needs-live" while the robot is not live,
// "moves" while the e-stop is latched. Shared by the Places and Routes panels.

/** A button labelled `label` of `className` calling `onClick`; `isLive()` says whether the robot is live. */
export function rowButton(label, className, onClick, isLive) {
  const b = document.createElement("button");
  b.type = "button";
  b.textContent = label;
  b.className = className;
  b.disabled = className.includes("needs-live") && !isLive() ||
    className.includes("moves") && document.body.dataset.estop === "1";
  b.onclick = onClick;
  return b;
}
