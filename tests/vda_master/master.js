#!/usr/bin/env node
/*
 * A VDA 5050 2.0.0 master for the tests: vda-5050-lib's MasterController (pinned in package.json),
 * driven over stdin/stdout by tests/vda_master.py.
 *
 * stdin: one JSON command a line, run one after the other. Each may carry an "id", echoed in its
 * reply (the one event that answers it: started, orderAssigned, orderDiscarded,
 * instantActionsInitiated, published, stopped, or error).
 *
 *   {"cmd": "start", "port": 1883, "host": "127.0.0.1", "interfaceName": "uagv",
 *    "manufacturer": "m", "serialNumber": "s"}
 *   {"cmd": "order", "order": {orderId, orderUpdateId, nodes, edges, ...}}       (headerless)
 *   {"cmd": "instantActions", "actions": [{actionId, actionType, blockingType, ...}]}
 *   {"cmd": "raw", "topic": "order", "payload": {...} or "text", "header": false, "retain": false}
 *   {"cmd": "stop"}
 *
 * stdout: one JSON event a line (see tests/vda_master.py for the list). Whatever the library drops
 * as invalid on the way in becomes {"event": "invalid", "by": "vda-5050-lib", ...}.
 * stderr: the library's own complaints (console.error), for a human.
 */
"use strict";

const readline = require("readline");
const { MasterController, Topic } = require("vda-5050-lib");
const LIB_VERSION = require("vda-5050-lib/package.json").version;

const VDA_VERSION = "2.0.0";
const INBOUND = [Topic.State, Topic.Connection, Topic.Visualization, Topic.Factsheet];

function emit(event) {
    // Pipes are written synchronously on Linux: a line is out before the next statement runs.
    process.stdout.write(JSON.stringify(event) + "\n");
}

function describe(error) {
    return error && error.message ? error.message : String(error);
}

// How vda-5050-lib 1.4.0 drops an inbound message (common/client.js, Client._dispatchMessage):
// JSON.parse, the subscription lookup and validateTopicObject (the version, then the JSON schema of
// the topic) run in one try; anything they throw is caught and only logged, with
//   console.error("Drop inbound message on MQTT topic %s with error: %s", mqttTopic, error.message)
// and no callback. So that log line is the one sure sign: it is turned into an "invalid" event here,
// with the payload the library was dispatching at the time (kept by HarnessMaster below).
const DROP = "Drop inbound message on MQTT topic";
let dispatching = null; // {mqttTopic, payload, dropped} while the library handles an inbound message
const consoleError = console.error.bind(console);
console.error = (...args) => {
    if (typeof args[0] === "string" && args[0].startsWith(DROP)) {
        const mqttTopic = String(args[1]);
        const event = { event: "invalid", by: "vda-5050-lib", topic: topicOf(mqttTopic), mqttTopic,
            error: String(args[2]) };
        if (dispatching && dispatching.mqttTopic === mqttTopic) {
            event.payload = dispatching.payload;
            dispatching.dropped = true;
        }
        emit(event);
    }
    consoleError(...args);
};

function topicOf(mqttTopic) {
    // The library's default topic format: interfaceName/v2/manufacturer/serialNumber/topic.
    return mqttTopic.split("/")[4];
}

class HarnessMaster extends MasterController {
    _dispatchMessage(mqttTopic, mqttPayload) {
        const payload = mqttPayload.toString();
        dispatching = { mqttTopic, payload, dropped: false };
        try {
            return super._dispatchMessage(mqttTopic, mqttPayload);
        } finally {
            if (!dispatching.dropped) {
                checkSubject(mqttTopic, payload);
            }
            dispatching = null;
        }
    }
}

if (typeof MasterController.prototype._dispatchMessage !== "function") {
    // Another version of the library: the hook above would see nothing.
    throw new Error(`vda-5050-lib ${LIB_VERSION} has no Client._dispatchMessage: invalid messages would go unseen`);
}

// What the library accepts but cannot use: it hands its handlers the AGV named in the payload, not
// in the topic, so a state whose manufacturer/serialNumber differ from its topic's reaches no order's
// callbacks, silently. Reported as invalid too (by: "harness").
function checkSubject(mqttTopic, payload) {
    const levels = mqttTopic.split("/");
    let object;
    try {
        object = JSON.parse(payload);
    } catch (error) {
        return; // the library said so already
    }
    if (object && (object.manufacturer !== levels[2] || object.serialNumber !== levels[3])) {
        emit({ event: "invalid", by: "harness", topic: levels[4], mqttTopic, payload,
            error: `payload names ${object.manufacturer}/${object.serialNumber}, topic ${levels[2]}/${levels[3]}` });
    }
}

let controller = null;
let agv = null; // {manufacturer, serialNumber} tracked since start

function requireStarted() {
    if (!controller) {
        throw new Error("the master is not started (send a start command first)");
    }
}

function orderIds(context) {
    return { orderId: context.order.orderId, orderUpdateId: context.order.orderUpdateId,
        stateHeaderId: context.state.headerId };
}

function target(nodeOrEdge) {
    if (!nodeOrEdge) {
        return null;
    }
    return nodeOrEdge.edgeId !== undefined ?
        { edgeId: nodeOrEdge.edgeId, sequenceId: nodeOrEdge.sequenceId } :
        { nodeId: nodeOrEdge.nodeId, sequenceId: nodeOrEdge.sequenceId };
}

function edgeFields(edge, startNode, endNode) {
    return { edgeId: edge.edgeId, sequenceId: edge.sequenceId,
        startNodeId: startNode ? startNode.nodeId : null, endNodeId: endNode ? endNode.nodeId : null };
}

function actionFields(actionState, action) {
    return { actionId: actionState.actionId, actionType: action.actionType,
        actionStatus: actionState.actionStatus,
        resultDescription: actionState.resultDescription === undefined ? null : actionState.resultDescription };
}

const commands = {
    async start(cmd) {
        if (controller) {
            throw new Error("already started");
        }
        const began = Date.now();
        const brokerUrl = cmd.brokerUrl || `mqtt://${cmd.host || "127.0.0.1"}:${cmd.port}`;
        const interfaceName = cmd.interfaceName || "uagv";
        const subject = { manufacturer: cmd.manufacturer, serialNumber: cmd.serialNumber };
        const master = new HarnessMaster(
            { interfaceName, vdaVersion: VDA_VERSION, transport: { brokerUrl, reconnectPeriod: 500, connectTimeout: 10000 } },
            { targetAgvs: subject });
        // Checked before start so that a bad AGV id fails the command, not later subscriptions.
        master.validateAgvId(subject, false);
        // The master's own MQTT connection ("online", "offline"): said when it changes.
        master.registerConnectionStateChange((state, previous) => {
            if (state !== previous) {
                emit({ event: "link", state });
            }
        });
        await master.start();
        controller = master;
        agv = subject;
        // The MasterController subscribed to state (for its order callbacks) and to every AGV's
        // connection; these add the AGV's four inbound topics as events. Each resolves on the SUBACK,
        // so all is listened to once "started" is out.
        for (const topic of INBOUND) {
            await master.subscribe(topic, subject, (object, agvId) => emit({ event: topic, agv: agvId, [topic]: object }));
        }
        const topics = {};
        for (const topic of Object.values(Topic)) {
            topics[topic] = master._subscriptionManager.getMqttTopic(topic, subject);
        }
        return { event: "started", lib: LIB_VERSION, vdaVersion: VDA_VERSION, brokerUrl, interfaceName,
            agv: subject, topics, ms: Date.now() - began };
    },

    async order(cmd) {
        requireStarted();
        const order = cmd.order;
        const handler = {
            onOrderProcessed: (error, byCancelation, active, context) => emit({ event: "orderProcessed",
                ...orderIds(context), error: error || null, byCancelation, active }),
            onNodeTraversed: (node, nextEdge, nextNode, context) => emit({ event: "nodeTraversed",
                ...orderIds(context), nodeId: node.nodeId, sequenceId: node.sequenceId,
                nextEdgeId: nextEdge ? nextEdge.edgeId : null, nextNodeId: nextNode ? nextNode.nodeId : null }),
            onEdgeTraversing: (edge, startNode, endNode, changes, invocation, context) => emit({
                event: "edgeTraversing", ...orderIds(context), ...edgeFields(edge, startNode, endNode),
                changes, invocation }),
            onEdgeTraversed: (edge, startNode, endNode, context) => emit({ event: "edgeTraversed",
                ...orderIds(context), ...edgeFields(edge, startNode, endNode) }),
            onActionStateChanged: (actionState, error, action, on, context) => emit({
                event: "actionStateChanged", source: "order", ...orderIds(context),
                ...actionFields(actionState, action), target: target(on), error: error || null }),
        };
        const sent = await controller.assignOrder(cmd.agv || agv, order, handler);
        if (sent === undefined) {
            // assignOrder discards an order whose orderId and orderUpdateId are those of one it still tracks.
            return { event: "orderDiscarded", orderId: order.orderId, orderUpdateId: order.orderUpdateId };
        }
        return { event: "orderAssigned", order: sent };
    },

    async instantActions(cmd) {
        requireStarted();
        const handler = {
            onActionStateChanged: (actionState, error, action, agvId, state) => emit({
                event: "actionStateChanged", source: "instant", ...actionFields(actionState, action),
                error: error || null, stateHeaderId: state.headerId }),
            onActionError: (error, action, agvId, state) => emit({ event: "actionError", source: "instant",
                actionId: action.actionId, actionType: action.actionType, error, stateHeaderId: state.headerId }),
        };
        const sent = await controller.initiateInstantActions(cmd.agv || agv, { instantActions: cmd.actions }, handler);
        return { event: "instantActionsInitiated", instantActions: sent };
    },

    // Whatever a test wants on an AGV topic, past the library's outbound validation (an invalid order,
    // a truncated JSON): a string goes out as it is, anything else as JSON. With "header": true the
    // library's own header is added first (its headerId counter for the topic moves on, as for orders).
    async raw(cmd) {
        requireStarted();
        const subject = cmd.agv || agv;
        const mqttTopic = cmd.mqttTopic || controller._subscriptionManager.getMqttTopic(cmd.topic, subject);
        let payload = cmd.payload;
        if (cmd.header) {
            payload = controller._withObjectHeader(cmd.topic, subject, payload);
        }
        const text = typeof payload === "string" ? payload : JSON.stringify(payload);
        await new Promise((resolve, reject) => controller._mqtt.publish(mqttTopic, text,
            { qos: 0, retain: Boolean(cmd.retain) }, error => (error ? reject(error) : resolve())));
        return { event: "published", topic: cmd.topic || topicOf(mqttTopic), mqttTopic, payload: text };
    },

    async stop() {
        if (controller) {
            const master = controller;
            controller = null;
            await master.stop();
        }
        return { event: "stopped" };
    },
};

async function run(line) {
    let cmd;
    try {
        cmd = JSON.parse(line);
    } catch (error) {
        emit({ event: "error", message: `not JSON: ${describe(error)}`, line });
        return;
    }
    const id = cmd && cmd.id;
    const name = cmd && cmd.cmd;
    try {
        if (!Object.prototype.hasOwnProperty.call(commands, name)) {
            throw new Error(`unknown command ${JSON.stringify(name)} (one of ${Object.keys(commands).join(", ")})`);
        }
        const reply = await commands[name](cmd);
        emit({ ...reply, id, cmd: name });
        if (name === "stop") {
            process.exit(0);
        }
    } catch (error) {
        emit({ event: "error", id, cmd: name, message: describe(error) });
    }
}

// The library calls our callbacks from its MQTT client's message handler; whatever escapes them (or
// the library) is said, not lost. The process carries on.
process.on("uncaughtException", error => emit({ event: "error", message: `uncaught: ${describe(error)}`,
    stack: error && error.stack }));
process.on("unhandledRejection", error => emit({ event: "error", message: `unhandled rejection: ${describe(error)}` }));

let queue = Promise.resolve();
const input = readline.createInterface({ input: process.stdin, terminal: false });
input.on("line", line => {
    if (line.trim()) {
        queue = queue.then(() => run(line));
    }
});
// stdin closed (the test process went away): stop as for a stop command.
input.on("close", () => {
    queue = queue.then(() => run(JSON.stringify({ cmd: "stop" })));
});

emit({ event: "ready", lib: LIB_VERSION, node: process.version, pid: process.pid });
