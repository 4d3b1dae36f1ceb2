// STOP, sent until the robot says it has stopped. On a Wi-Fi that drops or stalls, one request
// can be lost or left unanswered: the button says what happened ("not delivered: not connected,
// trying again") and sends again until the robot acknowledges, then says "stopped". A newer
// motion command from this page (a goal, the joystick) ends the retries: it is what the person
// wants now, and a stop retried after it would undo it.
import {api} from "./api.js";
import {words} from "./words.js";

const TRY_TIMEOUT_MS = 2000;
const RETRY_MS = [300, 600, 1000];  // then once a second, for as long as it takes
const DONE_SHOWN_MS = 2500;

export class StopSender {
  constructor(button) {
    this.button = button;
    this.attempt = 0;
    this.doneTimer = null;
  }

  /** Send a stop now, and again until acknowledged (or a newer command is sent). `quiet`: the
   *  joystick let go, not the STOP button: say something only if it does not get through. */
  async send(quiet = false) {
    const mine = ++this.attempt;
    if (!quiet) this.show("sending", "sending…");
    for (let tries = 0; mine === this.attempt; tries++) {
      try {
        await api("POST", "/stop", undefined, TRY_TIMEOUT_MS);
        if (mine === this.attempt) {
          if (!quiet || this.button.dataset.outcome) this.done();  // a quiet stop that had to retry says it landed
        }
        return true;
      } catch (e) {
        if (mine !== this.attempt) return false;
        if (e.status && e.status !== 401 && e.status < 500) {  // refused, not lost: trying again changes nothing
          this.show("refused", words(e, "stop"));
          return false;
        }
        const why = e.code === "no_answer" ? "no answer" : e.code === "not_connected" ? "not connected" : words(e, "stop");
        this.show("retrying", "did not reach the robot: " + why + ", retrying");
        await sleep(RETRY_MS[Math.min(tries, RETRY_MS.length - 1)] || 1000);
      }
    }
    return false;
  }

  /** A newer motion command went out: stop retrying, say nothing more about the old stop. */
  cancel() {
    if (this.button.dataset.outcome === "retrying" || this.button.dataset.outcome === "sending") {
      this.attempt++;
      this.show("", "");
    }
  }

  done() {
    this.show("stopped", "stopped ✓");
    clearTimeout(this.doneTimer);
    this.doneTimer = setTimeout(() => { if (this.button.dataset.outcome === "stopped") this.show("", ""); }, DONE_SHOWN_MS);
  }

  show(outcome, text) {
    this.button.dataset.outcome = outcome;
    this.button.querySelector(".outcome").textContent = text;
  }
}

const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
