// The VS Code client: starts `pccl lsp` (setting pccl.server.command) for
// .pccl files and their world files.
const vscode = require("vscode");
const { LanguageClient } = require("vscode-languageclient/node");

let client;

function activate(context) {
  const config = vscode.workspace.getConfiguration("pccl");
  const [command, ...args] = config.get("server.command", ["pccl", "lsp"]);
  // world files are claimed only by the patterns the user opts into (not
  // every *.toml: pyproject.toml is not a world)
  const worlds = config.get("worldFiles", ["**/*.world.toml"]);
  client = new LanguageClient(
    "pccl",
    "PCCL language server",
    { command, args },
    {
      documentSelector: [
        { scheme: "file", language: "pccl" },
        ...worlds.map((pattern) => ({ scheme: "file", pattern })),
      ],
    }
  );
  context.subscriptions.push(client);
  return client.start();
}

function deactivate() {
  return client ? client.stop() : undefined;
}

module.exports = { activate, deactivate };
